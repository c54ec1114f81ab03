#include "nurbsreg/io/step_reader.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <set>
#include <vector>

#include "nurbsreg/io/errors.hpp"
#include "text_io.hpp"

namespace nurbsreg::io {
namespace {

// One parameter of an ISO 10303-21 entity instance (Part 21 §6-§7): unset ($), derived (*),
// number, string, enumeration (.T.), instance reference (#12), list, or a typed parameter
// such as LENGTH_MEASURE(1.) whose arguments are in `items`.
struct Value {
  enum class Kind { unset, derived, number, string, enumeration, reference, list, typed };
  Kind kind = Kind::unset;
  double number = 0.0;
  std::int64_t reference = 0;
  std::string text;          // string contents, enumeration name or typed-parameter keyword
  std::vector<Value> items;  // list elements or typed-parameter arguments
};

// One partial entity: a keyword and its arguments. A simple instance has one part; a complex
// instance `( A(..) B(..) )` has one per supertype, each with only its own attributes.
struct Part {
  std::string keyword;
  std::vector<Value> args;
};

const char* kind_name(Value::Kind kind) {
  switch (kind) {
    case Value::Kind::unset:
      return "$";
    case Value::Kind::derived:
      return "*";
    case Value::Kind::number:
      return "a number";
    case Value::Kind::string:
      return "a string";
    case Value::Kind::enumeration:
      return "an enumeration";
    case Value::Kind::reference:
      return "a reference";
    case Value::Kind::list:
      return "a list";
    case Value::Kind::typed:
      return "a typed value";
  }
  return "?";
}

// Recursive-descent parser for one entity body (the text after `#id =`, without the `;`).
class BodyParser {
 public:
  BodyParser(std::string_view body, std::string_view text, const std::string& file)
      : body_(body), text_(text), file_(file) {}

  std::vector<Part> parse() {
    std::vector<Part> parts;
    skip_blanks();
    if (peek() == '(') {  // complex instance
      ++pos_;
      skip_blanks();
      while (peek() != ')') {
        if (at_end()) fail("unterminated complex entity");
        parts.push_back(parse_part());
        skip_blanks();
      }
      ++pos_;
    } else {
      parts.push_back(parse_part());
    }
    skip_blanks();
    if (!at_end()) fail("unexpected text after the entity");
    return parts;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    const std::size_t offset = static_cast<std::size_t>(body_.data() - text_.data()) + pos_;
    const auto position = text_detail::position_of(text_, offset);
    throw InputError(file_, "line " + std::to_string(position.line) + ": invalid STEP: " + what);
  }
  bool at_end() const { return pos_ >= body_.size(); }
  char peek() const { return at_end() ? '\0' : body_[pos_]; }
  // Whitespace and comments (`/* ... */`, allowed between any two tokens).
  void skip_blanks() {
    while (!at_end()) {
      if (std::isspace(static_cast<unsigned char>(body_[pos_]))) {
        ++pos_;
      } else if (body_.substr(pos_, 2) == "/*") {
        const std::size_t end = body_.find("*/", pos_ + 2);
        pos_ = end == std::string_view::npos ? body_.size() : end + 2;
      } else {
        break;
      }
    }
  }
  std::string keyword() {
    const std::size_t start = pos_;
    while (!at_end() && (std::isalnum(static_cast<unsigned char>(body_[pos_])) ||
                         body_[pos_] == '_' || body_[pos_] == '-')) {
      ++pos_;
    }
    if (pos_ == start) fail(std::string("expected an entity keyword, found '") + peek() + "'");
    std::string word(body_.substr(start, pos_ - start));
    for (char& ch : word)
      ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
    return word;
  }
  Part parse_part() {
    Part part;
    part.keyword = keyword();
    skip_blanks();
    part.args = parse_list().items;
    return part;
  }
  Value parse_list() {
    if (peek() != '(') fail("expected '('");
    // Real schemas nest a few levels (lists of lists of references); a bound keeps a corrupt
    // file from exhausting the stack of this recursive parser.
    if (++depth_ > kMaxDepth) fail("lists nested more than " + std::to_string(kMaxDepth) + " deep");
    ++pos_;
    Value list;
    list.kind = Value::Kind::list;
    skip_blanks();
    if (peek() == ')') {
      ++pos_;
      --depth_;
      return list;
    }
    while (true) {
      list.items.push_back(parse_value());
      skip_blanks();
      if (peek() == ',') {
        ++pos_;
        continue;
      }
      if (peek() == ')') {
        ++pos_;
        --depth_;
        return list;
      }
      fail(at_end() ? "unterminated list"
                    : std::string("expected ',' or ')', found '") + peek() + "'");
    }
  }
  Value parse_value() {
    skip_blanks();
    Value v;
    const char c = peek();
    if (c == '$') {
      ++pos_;
    } else if (c == '*') {
      ++pos_;
      v.kind = Value::Kind::derived;
    } else if (c == '(') {
      v = parse_list();
    } else if (c == '\'') {
      v.kind = Value::Kind::string;
      ++pos_;
      while (true) {
        if (at_end()) fail("unterminated string");
        const char ch = body_[pos_++];
        if (ch == '\'') {
          if (peek() != '\'') break;
          ++pos_;  // '' is an escaped quote
        }
        // Line breaks are not part of Part 21 strings (long strings are wrapped).
        if (ch != '\n' && ch != '\r') v.text += ch;
      }
    } else if (c == '"') {  // binary: kept as text, never needed for geometry
      v.kind = Value::Kind::string;
      const std::size_t end = body_.find('"', pos_ + 1);
      if (end == std::string_view::npos) fail("unterminated binary value");
      v.text = std::string(body_.substr(pos_ + 1, end - pos_ - 1));
      pos_ = end + 1;
    } else if (c == '.') {
      v.kind = Value::Kind::enumeration;
      const std::size_t end = body_.find('.', pos_ + 1);
      if (end == std::string_view::npos) fail("unterminated enumeration");
      v.text = std::string(body_.substr(pos_ + 1, end - pos_ - 1));
      pos_ = end + 1;
    } else if (c == '#') {
      v.kind = Value::Kind::reference;
      ++pos_;
      const auto result =
          std::from_chars(body_.data() + pos_, body_.data() + body_.size(), v.reference);
      if (result.ec != std::errc()) fail("expected an entity number after '#'");
      pos_ = static_cast<std::size_t>(result.ptr - body_.data());
    } else if (c == '+' || c == '-' || std::isdigit(static_cast<unsigned char>(c))) {
      v.kind = Value::Kind::number;
      std::size_t end = pos_ + 1;
      while (end < body_.size() && (std::isdigit(static_cast<unsigned char>(body_[end])) ||
                                    body_[end] == '.' || body_[end] == 'E' || body_[end] == 'e' ||
                                    ((body_[end] == '+' || body_[end] == '-') &&
                                     (body_[end - 1] == 'E' || body_[end - 1] == 'e')))) {
        ++end;
      }
      if (!text_detail::parse_number(body_.substr(pos_, end - pos_), v.number)) {
        fail("\"" + std::string(body_.substr(pos_, end - pos_)) + "\" is not a number");
      }
      pos_ = end;
    } else if (std::isalpha(static_cast<unsigned char>(c))) {
      v.kind = Value::Kind::typed;
      v.text = keyword();
      skip_blanks();
      v.items = parse_list().items;
    } else {
      fail(at_end() ? "unexpected end of entity" : std::string("unexpected character '") + c + "'");
    }
    return v;
  }

  static constexpr int kMaxDepth = 64;

  std::string_view body_;
  std::string_view text_;
  const std::string& file_;
  std::size_t pos_ = 0;
  int depth_ = 0;
};

// The exchange structure's instances: `#id = body;` statements, found by a scan that respects
// strings and comments (a ';' inside either does not end a statement).
class StepFile {
 public:
  StepFile(std::string_view text, const std::string& file) : text_(text), file_(file) { split(); }

  const std::map<std::int64_t, std::string_view>& bodies() const { return bodies_; }

  std::vector<Part> parts(std::int64_t id) const {
    const auto it = bodies_.find(id);
    if (it == bodies_.end())
      throw InputError(file_, "#" + std::to_string(id) + ": referenced but not defined");
    return BodyParser(it->second, text_, file_).parse();
  }

  // The keyword a body starts with ("" for a complex instance).
  static std::string_view leading_keyword(std::string_view body) {
    std::size_t start = 0;
    while (start < body.size() && std::isspace(static_cast<unsigned char>(body[start])))
      ++start;
    std::size_t end = start;
    while (end < body.size() &&
           (std::isalnum(static_cast<unsigned char>(body[end])) || body[end] == '_')) {
      ++end;
    }
    return body.substr(start, end - start);
  }

  const std::string& file() const { return file_; }

 private:
  void split() {
    std::size_t statement_start = 0;
    std::size_t i = 0;
    bool in_data = false;
    while (i < text_.size()) {
      const char c = text_[i];
      if (c == '\'') {
        ++i;
        while (i < text_.size() &&
               !(text_[i] == '\'' && (i + 1 >= text_.size() || text_[i + 1] != '\''))) {
          i += text_[i] == '\'' ? 2 : 1;
        }
        ++i;
      } else if (c == '/' && i + 1 < text_.size() && text_[i + 1] == '*') {
        const std::size_t end = text_.find("*/", i + 2);
        i = end == std::string_view::npos ? text_.size() : end + 2;
      } else if (c == ';') {
        statement(text_.substr(statement_start, i - statement_start), statement_start, in_data);
        statement_start = ++i;
      } else {
        ++i;
      }
    }
    if (bodies_.empty()) {
      throw InputError(file_, text_.substr(0, 12) == "ISO-10303-21"
                                  ? "no entity instances in the DATA section"
                                  : "not a STEP file (ISO-10303-21 exchange structure expected)");
    }
  }

  void statement(std::string_view s, std::size_t offset, bool& in_data) {
    std::size_t start = 0;
    while (start < s.size()) {
      if (std::isspace(static_cast<unsigned char>(s[start]))) {
        ++start;
      } else if (s.substr(start, 2) == "/*") {
        const std::size_t end = s.find("*/", start + 2);
        start = end == std::string_view::npos ? s.size() : end + 2;
      } else {
        break;
      }
    }
    s.remove_prefix(start);
    offset += start;
    if (s == "DATA" || s.substr(0, 5) == "DATA(") {
      in_data = true;
      return;
    }
    if (s == "ENDSEC") {
      in_data = false;
      return;
    }
    if (!in_data || s.empty() || s.front() != '#') return;
    std::int64_t id = 0;
    const auto result = std::from_chars(s.data() + 1, s.data() + s.size(), id);
    const std::size_t eq = s.find('=');
    if (result.ec != std::errc() || eq == std::string_view::npos) {
      const auto position = text_detail::position_of(text_, offset);
      throw InputError(file_, "line " + std::to_string(position.line) +
                                  ": invalid STEP: expected `#<number> = <entity>;`");
    }
    bodies_[id] = s.substr(eq + 1);
  }

  std::string_view text_;
  const std::string& file_;
  std::map<std::int64_t, std::string_view> bodies_;
};

const Part* find_part(const std::vector<Part>& parts, std::string_view keyword) {
  for (const Part& p : parts) {
    if (p.keyword == keyword) return &p;
  }
  return nullptr;
}

// Reads the attributes of one B-spline surface instance, throwing InputError that names it.
class SurfaceBuilder {
 public:
  SurfaceBuilder(const StepFile& step, std::int64_t id, const std::vector<Part>& parts)
      : step_(step), id_(id), parts_(parts) {
    label_ = "#" + std::to_string(id) + " B_SPLINE_SURFACE_WITH_KNOTS";
  }

  engine::NurbsSurface build() {
    engine::NurbsSurface s;
    const Part* knots = find_part(parts_, "B_SPLINE_SURFACE_WITH_KNOTS");
    const Value* degree_u = nullptr;
    const Value* degree_v = nullptr;
    const Value* points = nullptr;
    const Value* knot_args = nullptr;  // u_multiplicities, v_multiplicities, u_knots, v_knots
    if (parts_.size() == 1) {
      // B_SPLINE_SURFACE_WITH_KNOTS(name, u_degree, v_degree, control_points_list, surface_form,
      //   u_closed, v_closed, self_intersect, u_multiplicities, v_multiplicities, u_knots,
      //   v_knots, knot_spec) -- ISO 10303-42 §4.4.
      require_args(*knots, 13);
      s.name = text_or_empty(knots->args[0]);
      degree_u = &knots->args[1];
      degree_v = &knots->args[2];
      points = &knots->args[3];
      knot_args = &knots->args[8];
    } else {
      const Part* surface = find_part(parts_, "B_SPLINE_SURFACE");
      if (surface == nullptr) fail("", "complex instance without a B_SPLINE_SURFACE part");
      // B_SPLINE_SURFACE(u_degree, v_degree, control_points_list, surface_form, u_closed,
      //   v_closed, self_intersect); B_SPLINE_SURFACE_WITH_KNOTS(u_multiplicities,
      //   v_multiplicities, u_knots, v_knots, knot_spec).
      require_args(*surface, 7);
      require_args(*knots, 5);
      degree_u = &surface->args[0];
      degree_v = &surface->args[1];
      points = &surface->args[2];
      knot_args = &knots->args[0];
      if (const Part* item = find_part(parts_, "REPRESENTATION_ITEM");
          item && !item->args.empty()) {
        s.name = text_or_empty(item->args[0]);
      }
    }
    if (s.name.empty()) s.name = "#" + std::to_string(id_);
    s.degree_u = integer(*degree_u, "u_degree");
    s.degree_v = integer(*degree_v, "v_degree");
    if (s.degree_u < 1 || s.degree_u > engine::kMaxDegree || s.degree_v < 1 ||
        s.degree_v > engine::kMaxDegree) {
      fail("degree", "(" + std::to_string(s.degree_u) + ", " + std::to_string(s.degree_v) +
                         ") is outside 1.." + std::to_string(engine::kMaxDegree));
    }
    s.knots_u = expand_knots(knot_args[0], knot_args[2], "u");
    s.knots_v = expand_knots(knot_args[1], knot_args[3], "v");

    const std::vector<Value>& rows = list(*points, "control_points_list").items;
    s.count_u = static_cast<int>(rows.size());
    s.count_v =
        rows.empty() ? 0 : static_cast<int>(list(rows[0], "control_points_list[0]").items.size());
    s.control_points.reserve(static_cast<std::size_t>(s.count_u) * s.count_v);
    for (int i = 0; i < s.count_u; ++i) {
      const std::string field = "control_points_list[" + std::to_string(i) + "]";
      const std::vector<Value>& row = list(rows[i], field).items;
      if (static_cast<int>(row.size()) != s.count_v) {
        fail(field, "has " + std::to_string(row.size()) + " points, row 0 has " +
                        std::to_string(s.count_v));
      }
      for (int j = 0; j < s.count_v; ++j)
        s.control_points.push_back(point(row[j], field));
    }

    if (const Part* rational = find_part(parts_, "RATIONAL_B_SPLINE_SURFACE")) {
      require_args(*rational, 1);
      const std::vector<Value>& weight_rows = list(rational->args[0], "weights_data").items;
      if (static_cast<int>(weight_rows.size()) != s.count_u) {
        fail("weights_data", "has " + std::to_string(weight_rows.size()) + " rows, expected " +
                                 std::to_string(s.count_u) + " (one per control point row)");
      }
      for (int i = 0; i < s.count_u; ++i) {
        const std::string field = "weights_data[" + std::to_string(i) + "]";
        const std::vector<Value>& row = list(weight_rows[i], field).items;
        if (static_cast<int>(row.size()) != s.count_v) {
          fail(field, "has " + std::to_string(row.size()) + " weights, expected " +
                          std::to_string(s.count_v));
        }
        for (const Value& w : row)
          s.weights.push_back(number(w, field));
      }
    }
    if (auto error = s.validate()) throw InputError(step_.file(), label_ + ": " + *error);
    return s;
  }

 private:
  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw InputError(step_.file(), label_ + ": " + (field.empty() ? "" : field + ": ") + what);
  }
  void require_args(const Part& part, std::size_t n) const {
    if (part.args.size() < n) {
      fail("", part.keyword + " has " + std::to_string(part.args.size()) +
                   " attributes, expected " + std::to_string(n));
    }
  }
  static std::string text_or_empty(const Value& v) {
    return v.kind == Value::Kind::string ? v.text : std::string();
  }
  const Value& list(const Value& v, const std::string& field) const {
    if (v.kind != Value::Kind::list)
      fail(field, std::string("expected a list, got ") + kind_name(v.kind));
    return v;
  }
  double number(const Value& v, const std::string& field) const {
    // Typed measures such as PARAMETER_VALUE(0.5) carry the number as their argument.
    if (v.kind == Value::Kind::typed && v.items.size() == 1) return number(v.items[0], field);
    if (v.kind != Value::Kind::number)
      fail(field, std::string("expected a number, got ") + kind_name(v.kind));
    return v.number;
  }
  int integer(const Value& v, const std::string& field) const {
    const double x = number(v, field);
    if (x != std::floor(x) || std::abs(x) > 1e9) fail(field, "expected an integer");
    return static_cast<int>(x);
  }
  std::vector<double> expand_knots(const Value& multiplicities, const Value& knots,
                                   const char* dir) const {
    const std::string mult_field = std::string(dir) + "_multiplicities";
    const std::string knot_field = std::string(dir) + "_knots";
    const std::vector<Value>& m = list(multiplicities, mult_field).items;
    const std::vector<Value>& k = list(knots, knot_field).items;
    if (m.size() != k.size()) {
      fail(mult_field, "has " + std::to_string(m.size()) + " values but " + knot_field + " has " +
                           std::to_string(k.size()));
    }
    std::vector<double> expanded;
    for (std::size_t i = 0; i < k.size(); ++i) {
      const int count = integer(m[i], mult_field);
      if (count < 1 || count > engine::kMaxDegree + 1) {
        fail(mult_field, "value " + std::to_string(count) + " at index " + std::to_string(i) +
                             " is outside 1.." + std::to_string(engine::kMaxDegree + 1));
      }
      expanded.insert(expanded.end(), static_cast<std::size_t>(count), number(k[i], knot_field));
    }
    return expanded;
  }
  engine::Vec3 point(const Value& ref, const std::string& field) const {
    if (ref.kind != Value::Kind::reference) fail(field, "expected a CARTESIAN_POINT reference");
    const std::vector<Part> parts = step_.parts(ref.reference);
    const std::string where = field + " #" + std::to_string(ref.reference);
    if (parts.size() != 1 || parts[0].keyword != "CARTESIAN_POINT" || parts[0].args.size() != 2) {
      fail(where, "expected CARTESIAN_POINT('name', (x, y, z)), got " + parts[0].keyword);
    }
    const std::vector<Value>& xyz = list(parts[0].args[1], where).items;
    if (xyz.size() != 3) fail(where, "expected 3 coordinates, got " + std::to_string(xyz.size()));
    return {number(xyz[0], where), number(xyz[1], where), number(xyz[2], where)};
  }

  const StepFile& step_;
  std::int64_t id_;
  const std::vector<Part>& parts_;
  std::string label_;
};

// The model's length unit from the first LENGTH_UNIT complex instance (by entity number).
std::string read_units(const StepFile& step, StepImportReport& report) {
  static const std::pair<const char*, const char*> kPrefixes[] = {{"MILLI", "mm"}, {"CENTI", "cm"},
                                                                  {"DECI", "dm"},  {"MICRO", "um"},
                                                                  {"NANO", "nm"},  {"KILO", "km"}};
  for (const auto& [id, body] : step.bodies()) {
    if (!StepFile::leading_keyword(body).empty() ||
        body.find("LENGTH_UNIT") == std::string_view::npos) {
      continue;
    }
    const std::vector<Part> parts = step.parts(id);
    if (find_part(parts, "LENGTH_UNIT") == nullptr) continue;
    report.units_source = "#" + std::to_string(id);
    if (const Part* si = find_part(parts, "SI_UNIT"); si && si->args.size() == 2) {
      if (si->args[1].kind != Value::Kind::enumeration || si->args[1].text != "METRE") continue;
      if (si->args[0].kind != Value::Kind::enumeration) return "m";
      for (const auto& [prefix, units] : kPrefixes) {
        if (si->args[0].text == prefix) return units;
      }
      return si->args[0].text + "METRE";
    }
    if (const Part* converted = find_part(parts, "CONVERSION_BASED_UNIT");
        converted && !converted->args.empty() && converted->args[0].kind == Value::Kind::string) {
      std::string name = converted->args[0].text;
      for (char& ch : name)
        ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
      if (!name.empty()) return name;
    }
  }
  report.units_source.clear();
  return engine::Model().units;
}

bool is_bspline_surface(const std::vector<Part>& parts) {
  return find_part(parts, "B_SPLINE_SURFACE_WITH_KNOTS") != nullptr;
}

// For the skipped-face statistics: the surface's type, complex instances as "A+B".
std::string type_name(const std::vector<Part>& parts) {
  if (parts.size() == 1) return parts[0].keyword;
  std::string name;
  for (const Part& p : parts) {
    if (p.keyword == "GEOMETRIC_REPRESENTATION_ITEM" || p.keyword == "REPRESENTATION_ITEM" ||
        p.keyword == "SURFACE" || p.keyword == "BOUNDED_SURFACE") {
      continue;
    }
    name += (name.empty() ? "" : "+") + p.keyword;
  }
  return name;
}

}  // namespace

engine::Model parse_step(std::string_view text, const std::string& file_label,
                         StepImportReport* report_out) {
  StepImportReport report;
  const StepFile step(text, file_label);
  engine::Model model;
  model.units = read_units(step, report);

  std::vector<std::int64_t> surface_ids;
  std::set<std::int64_t> seen;
  for (const auto& [id, body] : step.bodies()) {
    const std::string_view keyword = StepFile::leading_keyword(body);
    if (keyword != "ADVANCED_FACE" && keyword != "FACE_SURFACE") continue;
    ++report.faces;
    // ADVANCED_FACE / FACE_SURFACE(name, bounds, face_geometry, same_sense).
    const std::vector<Part> face = step.parts(id);
    if (face[0].args.size() != 4 || face[0].args[2].kind != Value::Kind::reference) {
      throw InputError(file_label, "#" + std::to_string(id) + " " + std::string(keyword) +
                                       ": expected (name, bounds, #surface, same_sense)");
    }
    const std::int64_t surface_id = face[0].args[2].reference;
    const std::vector<Part> surface = step.parts(surface_id);
    if (!is_bspline_surface(surface)) {
      ++report.skipped_faces[type_name(surface)];
      continue;
    }
    ++report.bspline_faces;
    if (seen.insert(surface_id).second) surface_ids.push_back(surface_id);
  }
  if (report.faces == 0) {
    // Bare geometry (no topology): every B-spline surface in the file.
    for (const auto& [id, body] : step.bodies()) {
      if (body.find("B_SPLINE_SURFACE_WITH_KNOTS") != std::string_view::npos)
        surface_ids.push_back(id);
    }
  }
  for (const std::int64_t id : surface_ids) {
    const std::vector<Part> parts = step.parts(id);
    if (!is_bspline_surface(parts)) continue;
    model.surfaces.push_back(SurfaceBuilder(step, id, parts).build());
    if (model.surfaces.back().is_rational()) ++report.rational_surfaces;
  }
  if (model.surfaces.empty()) {
    std::string skipped;
    for (const auto& [type, count] : report.skipped_faces) {
      skipped += (skipped.empty() ? "" : ", ") + std::to_string(count) + " " + type;
    }
    throw InputError(file_label, "no B-spline surfaces to import (" + std::to_string(report.faces) +
                                     " faces" + (skipped.empty() ? "" : ": " + skipped) + ")");
  }
  if (report_out != nullptr) *report_out = std::move(report);
  return model;
}

engine::Model read_step(const std::string& path, StepImportReport* report) {
  const std::string text = text_detail::read_text_file(path);
  return parse_step(text, path, report);
}

}  // namespace nurbsreg::io
