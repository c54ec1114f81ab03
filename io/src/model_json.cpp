#include "nurbsreg/io/model_json.hpp"

#include <cmath>
#include <nlohmann/json.hpp>

#include "model_ranges.hpp"
#include "nurbsreg/io/atomic_file.hpp"
#include "nurbsreg/io/errors.hpp"
#include "printable.hpp"
#include "text_io.hpp"

namespace nurbsreg::io {
namespace {

using nlohmann::json;

// What a JSON value is, for messages: `got a string ("abc")` reads better than a type code.
std::string describe(const json& value) {
  switch (value.type()) {
    case json::value_t::null:
      return "null";
    case json::value_t::boolean:
      return value.get<bool>() ? "true" : "false";
    case json::value_t::string: {
      // JSON escapes control characters but keeps DEL and UTF-8 as they are: bytes outside
      // printable ASCII become \xHH, so that the message stays one printable line.
      std::string text = text_detail::printable(
          value.dump(-1, ' ', /*ensure_ascii=*/false, json::error_handler_t::replace));
      if (text.size() > 40) text = text.substr(0, 37) + "...\"";
      return "a string (" + text + ")";
    }
    case json::value_t::array:
      return "an array of " + std::to_string(value.size());
    case json::value_t::object:
      return "an object";
    default:
      return "the number " + value.dump();
  }
}

// Reads one entity (or the top level) and throws InputError prefixed with the entity label,
// so every message names the file, the entity and the field.
class EntityReader {
 public:
  EntityReader(const std::string& file, std::string label)
      : file_(file), label_(std::move(label)) {}

  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    std::string message = label_;
    if (!field.empty()) message += (message.empty() ? "" : ": ") + field;
    throw InputError(file_, message + ": " + what);
  }

  // Adds `"name"` to the label once the entity's name is known.
  void set_name(const std::string& name) {
    // Escaped (text_io.hpp), so that a message stays one printable line whatever the name.
    if (!name.empty()) label_ += " " + text_detail::quote_name(name);
  }
  const std::string& label() const { return label_; }

  double number(const json& value, const std::string& field) const {
    if (!value.is_number()) fail(field, "expected a number, got " + describe(value));
    return value.get<double>();
  }

  // Integers may be written as 3 or 3.0; 3.5 is an error.
  int integer(const json& value, const std::string& field) const {
    if (value.is_number_integer()) {
      const auto x = value.get<std::int64_t>();
      if (x < -1'000'000 || x > 1'000'000)
        fail(field, "integer out of range (" + value.dump() + ")");
      return static_cast<int>(x);
    }
    if (value.is_number_float()) {
      const double x = value.get<double>();
      if (x == std::floor(x) && std::abs(x) <= 1e6) return static_cast<int>(x);
    }
    fail(field, "expected an integer, got " + describe(value));
  }

  const json& array(const json& value, const std::string& field) const {
    if (!value.is_array()) fail(field, "expected an array, got " + describe(value));
    return value;
  }

  std::vector<double> numbers(const json& value, const std::string& field) const {
    array(value, field);
    std::vector<double> out;
    out.reserve(value.size());
    for (std::size_t i = 0; i < value.size(); ++i) {
      out.push_back(number(value[i], field + "[" + std::to_string(i) + "]"));
    }
    return out;
  }

  // A point [x, y, z], or [x, y] (z = 0) when `allow_2d`. Returns the number of coordinates.
  int point(const json& value, const std::string& field, bool allow_2d, engine::Vec3& out) const {
    const char* expected =
        allow_2d ? "expected 2 or 3 numbers [x, y(, z)]" : "expected 3 numbers [x, y, z]";
    if (!value.is_array()) fail(field, std::string(expected) + ", got " + describe(value));
    const std::size_t n = value.size();
    if (!(n == 3 || (allow_2d && n == 2)))
      fail(field, std::string(expected) + ", got " + std::to_string(n));
    out.setZero();
    for (std::size_t k = 0; k < n; ++k) {
      out[static_cast<int>(k)] = number(value[k], field + "[" + std::to_string(k) + "]");
    }
    return static_cast<int>(n);
  }

  // The value of a required key; objects are checked by the caller.
  const json& required(const json& object, const char* key) const {
    const auto it = object.find(key);
    if (it == object.end()) fail(key, "missing (required)");
    return *it;
  }

 private:
  const std::string& file_;
  std::string label_;
};

// Optional keys may also be given as null, which reads as absent.
const json* optional(const json& object, const char* key) {
  const auto it = object.find(key);
  if (it == object.end() || it->is_null()) return nullptr;
  return &*it;
}

std::string read_name(EntityReader& reader, const json& entity) {
  const json* name = optional(entity, "name");
  if (name == nullptr) return {};
  if (!name->is_string()) reader.fail("name", "expected a string, got " + describe(*name));
  reader.set_name(name->get<std::string>());
  return name->get<std::string>();
}

// The number of control points a knot vector implies, checked before the control points are
// read so that a wrong count is reported against the knots, with the arithmetic spelled out.
int implied_count(const EntityReader& reader, const char* field, std::size_t knot_count,
                  int degree) {
  const long long count = static_cast<long long>(knot_count) - degree - 1;
  if (count < degree + 1) {
    reader.fail(field, "has " + std::to_string(knot_count) + " values; degree " +
                           std::to_string(degree) + " needs at least " +
                           std::to_string(2 * (degree + 1)) + " (2 x (degree + 1))");
  }
  return static_cast<int>(count);
}

// Knot errors (decreasing, empty domain, multiplicity above the degree) before any control point
// is read, reported against `field`. The engine's rules are reused through a placeholder curve
// whose count comes from the knot vector itself, so the allocation is bounded by the file size.
void check_knot_vector(const EntityReader& reader, const char* field,
                       const std::vector<double>& knots, int degree, int count) {
  engine::NurbsCurve probe;
  probe.degree = degree;
  probe.knots = knots;
  probe.control_points.assign(static_cast<std::size_t>(count), engine::Vec3::Zero());
  if (auto error = probe.validate()) {
    // Degree and count were checked already, so the message is about "knots...".
    const std::string_view rest = std::string_view(*error).substr(std::string_view("knots").size());
    reader.fail(field + std::string(rest.substr(0, rest.find(':'))),
                std::string(rest.substr(std::min(rest.size(), rest.find(':') + 2))));
  }
}

// A curve object (CONTRACT.md) read with `reader`, whose label names where it is.
engine::NurbsCurve parse_curve(EntityReader& reader, const json& entity) {
  if (!entity.is_object()) reader.fail("", "expected an object, got " + describe(entity));
  engine::NurbsCurve c;
  c.name = read_name(reader, entity);

  c.degree = reader.integer(reader.required(entity, "degree"), "degree");
  if (c.degree < 1 || c.degree > engine::kMaxDegree) {
    reader.fail("degree", "must be between 1 and " + std::to_string(engine::kMaxDegree) + " (got " +
                              std::to_string(c.degree) + ")");
  }
  c.knots = reader.numbers(reader.required(entity, "knots"), "knots");
  const int count = implied_count(reader, "knots", c.knots.size(), c.degree);
  check_knot_vector(reader, "knots", c.knots, c.degree, count);
  c.control_points.resize(static_cast<std::size_t>(count));

  const json& points = reader.array(reader.required(entity, "control_points"), "control_points");
  if (points.size() != static_cast<std::size_t>(count)) {
    reader.fail("control_points",
                "expected " + std::to_string(count) +
                    " points (len(knots) - degree - 1 = " + std::to_string(c.knots.size()) + " - " +
                    std::to_string(c.degree) + " - 1), got " + std::to_string(points.size()));
  }
  for (int i = 0; i < count; ++i) {
    const std::string field = "control_points[" + std::to_string(i) + "]";
    const int dimension = reader.point(points[i], field, true, c.control_points[i]);
    // One dimension per curve: a mix of [x, y] and [x, y, z] is almost surely a typo.
    if (i == 0) {
      c.dimension = dimension;
    } else if (dimension != c.dimension) {
      reader.fail(field, "has " + std::to_string(dimension) +
                             " coordinates but control_points[0] has " +
                             std::to_string(c.dimension) + " (all points of a curve must agree)");
    }
  }

  if (const json* weights = optional(entity, "weights")) {
    c.weights = reader.numbers(*weights, "weights");
    if (c.weights.size() != static_cast<std::size_t>(count)) {
      reader.fail("weights", "expected " + std::to_string(count) +
                                 " values (one per control point), got " +
                                 std::to_string(c.weights.size()));
    }
  }
  return c;
}

engine::NurbsCurve read_curve(const std::string& file, std::size_t index, const json& entity) {
  EntityReader reader(file, "curve " + std::to_string(index));
  return parse_curve(reader, entity);
}

// "trim_loops": [{"curves": [{"uv": <2-D curve>, "edge": <3-D curve, optional>}, ...]}, ...]
// (README.md, "Model format: trimmed faces"). Dimensions and domains are the engine's rules,
// checked by validate() afterwards.
std::vector<engine::TrimLoop> read_trim_loops(const std::string& file, const EntityReader& reader,
                                              const json& value) {
  reader.array(value, "trim_loops");
  std::vector<engine::TrimLoop> loops(value.size());
  for (std::size_t l = 0; l < value.size(); ++l) {
    const std::string loop_field = "trim_loops[" + std::to_string(l) + "]";
    const json& loop = value[l];
    if (!loop.is_object()) reader.fail(loop_field, "expected an object, got " + describe(loop));
    const auto curves_it = loop.find("curves");
    if (curves_it == loop.end()) reader.fail(loop_field + ".curves", "missing (required)");
    const json& curves = reader.array(*curves_it, loop_field + ".curves");
    for (std::size_t c = 0; c < curves.size(); ++c) {
      const std::string field = loop_field + ".curves[" + std::to_string(c) + "]";
      const json& entry = curves[c];
      if (!entry.is_object()) reader.fail(field, "expected an object, got " + describe(entry));
      const auto uv = entry.find("uv");
      if (uv == entry.end()) reader.fail(field + ".uv", "missing (required)");
      engine::TrimCurve curve;
      EntityReader uv_reader(file, reader.label() + ": " + field + ".uv");
      curve.uv = parse_curve(uv_reader, *uv);
      if (const json* edge = optional(entry, "edge")) {
        EntityReader edge_reader(file, reader.label() + ": " + field + ".edge");
        curve.edge = parse_curve(edge_reader, *edge);
      }
      loops[l].curves.push_back(std::move(curve));
    }
  }
  return loops;
}

std::vector<engine::SkippedFace> read_skipped_faces(const EntityReader& top, const json& value) {
  top.array(value, "skipped_faces");
  std::vector<engine::SkippedFace> out;
  for (std::size_t i = 0; i < value.size(); ++i) {
    const std::string field = "skipped_faces[" + std::to_string(i) + "]";
    const json& entry = value[i];
    if (!entry.is_object()) top.fail(field, "expected an object, got " + describe(entry));
    engine::SkippedFace face;
    const auto index = entry.find("face");
    if (index == entry.end()) top.fail(field + ".face", "missing (required)");
    face.face = top.integer(*index, field + ".face");
    if (face.face < 0) top.fail(field + ".face", "must be >= 0 (got " + index->dump() + ")");
    const auto reason = entry.find("reason");
    if (reason == entry.end()) top.fail(field + ".reason", "missing (required)");
    if (!reason->is_string())
      top.fail(field + ".reason", "expected a string, got " + describe(*reason));
    face.reason = reason->get<std::string>();
    out.push_back(std::move(face));
  }
  return out;
}

engine::NurbsSurface read_surface(const std::string& file, std::size_t index, const json& entity) {
  EntityReader reader(file, "surface " + std::to_string(index));
  if (!entity.is_object()) reader.fail("", "expected an object, got " + describe(entity));
  engine::NurbsSurface s;
  s.name = read_name(reader, entity);

  const json& degree = reader.array(reader.required(entity, "degree"), "degree");
  if (degree.size() != 2) {
    reader.fail("degree",
                "expected [degree_u, degree_v], got an array of " + std::to_string(degree.size()));
  }
  s.degree_u = reader.integer(degree[0], "degree[0]");
  s.degree_v = reader.integer(degree[1], "degree[1]");
  if (s.degree_u < 1 || s.degree_u > engine::kMaxDegree || s.degree_v < 1 ||
      s.degree_v > engine::kMaxDegree) {
    reader.fail("degree", "must be between 1 and " + std::to_string(engine::kMaxDegree) +
                              " (got [" + std::to_string(s.degree_u) + ", " +
                              std::to_string(s.degree_v) + "])");
  }
  s.knots_u = reader.numbers(reader.required(entity, "knots_u"), "knots_u");
  s.knots_v = reader.numbers(reader.required(entity, "knots_v"), "knots_v");
  s.count_u = implied_count(reader, "knots_u", s.knots_u.size(), s.degree_u);
  s.count_v = implied_count(reader, "knots_v", s.knots_v.size(), s.degree_v);
  check_knot_vector(reader, "knots_u", s.knots_u, s.degree_u, s.count_u);
  check_knot_vector(reader, "knots_v", s.knots_v, s.degree_v, s.count_v);

  const std::string shape =
      std::to_string(s.count_u) + " rows of " + std::to_string(s.count_v) +
      " (count_u = len(knots_u) - degree_u - 1 = " + std::to_string(s.knots_u.size()) + " - " +
      std::to_string(s.degree_u) + " - 1, count_v likewise)";
  const json& rows = reader.array(reader.required(entity, "control_points"), "control_points");
  if (rows.size() != static_cast<std::size_t>(s.count_u)) {
    reader.fail("control_points",
                "expected " + shape + ", got " + std::to_string(rows.size()) + " rows");
  }
  // Every row's length first: only then is count_u x count_v known to match the file's size.
  for (int i = 0; i < s.count_u; ++i) {
    const std::string row_field = "control_points[" + std::to_string(i) + "]";
    const json& row = reader.array(rows[i], row_field);
    if (row.size() != static_cast<std::size_t>(s.count_v)) {
      reader.fail(row_field, "expected " + std::to_string(s.count_v) + " points (count_v), got " +
                                 std::to_string(row.size()));
    }
  }
  s.control_points.resize(static_cast<std::size_t>(s.count_u) * s.count_v);
  for (int i = 0; i < s.count_u; ++i) {
    const std::string row_field = "control_points[" + std::to_string(i) + "]";
    for (int j = 0; j < s.count_v; ++j) {
      reader.point(rows[i][j], row_field + "[" + std::to_string(j) + "]", false,
                   s.control_points[static_cast<std::size_t>(i) * s.count_v + j]);
    }
  }

  if (const json* weights = optional(entity, "weights")) {
    reader.array(*weights, "weights");
    if (weights->size() != static_cast<std::size_t>(s.count_u)) {
      reader.fail("weights", "expected " + std::to_string(s.count_u) +
                                 " rows (same nesting as control_points), got " +
                                 std::to_string(weights->size()));
    }
    s.weights.reserve(s.control_points.size());
    for (int i = 0; i < s.count_u; ++i) {
      const std::string row_field = "weights[" + std::to_string(i) + "]";
      const std::vector<double> row = reader.numbers((*weights)[i], row_field);
      if (row.size() != static_cast<std::size_t>(s.count_v)) {
        reader.fail(row_field, "expected " + std::to_string(s.count_v) + " values (count_v), got " +
                                   std::to_string(row.size()));
      }
      s.weights.insert(s.weights.end(), row.begin(), row.end());
    }
  }
  if (const json* loops = optional(entity, "trim_loops"))
    s.trim_loops = read_trim_loops(file, reader, *loops);
  if (const json* reversed = optional(entity, "reversed")) {
    if (!reversed->is_boolean())
      reader.fail("reversed", "expected true or false, got " + describe(*reversed));
    s.reversed = reversed->get<bool>();
  }
  return s;
}

// nlohmann's message is "[json.exception.parse_error.101] parse error at line L, column C:
// <what>"; the position is recomputed from the byte offset so the format stays ours.
std::string syntax_message(std::string_view text, const json::parse_error& error) {
  std::string what = error.what();
  const std::size_t colon = what.find(": ", what.find("column"));
  what = colon == std::string::npos ? what : what.substr(colon + 2);
  // e.byte is 1-based and points one past the offending character.
  const auto position = text_detail::position_of(text, error.byte == 0 ? 0 : error.byte - 1);
  return "line " + std::to_string(position.line) + ", column " + std::to_string(position.column) +
         ": invalid JSON: " + text_detail::printable(what);
}

void append_point(std::string& out, const engine::Vec3& p, int dimension) {
  out += '[';
  for (int k = 0; k < dimension; ++k) {
    if (k > 0) out += ", ";
    text_detail::append_number(out, p[k]);
  }
  out += ']';
}

void append_numbers(std::string& out, const double* values, std::size_t n) {
  out += '[';
  for (std::size_t k = 0; k < n; ++k) {
    if (k > 0) out += ", ";
    text_detail::append_number(out, values[k]);
  }
  out += ']';
}

void append_string(std::string& out, const std::string& s) {
  out += json(s).dump();
}

// A curve object; `indent` is the indentation of its braces. Nested (trim) curves write their
// name only when they have one.
void append_curve(std::string& out, const engine::NurbsCurve& c, const std::string& indent,
                  bool always_name) {
  const std::string in = "\n" + indent + "  ";
  out += indent + "{";
  const char* separator = "";
  if (always_name || !c.name.empty()) {
    out += in + "\"name\": ";
    append_string(out, c.name);
    separator = ",";
  }
  out += separator + in + "\"degree\": " + std::to_string(c.degree) + "," + in + "\"knots\": ";
  append_numbers(out, c.knots.data(), c.knots.size());
  out += "," + in + "\"control_points\": [";
  for (int i = 0; i < c.count(); ++i) {
    out += (i == 0 ? "" : ",") + in + "  ";
    append_point(out, c.control_points[i], c.dimension == 2 ? 2 : 3);
  }
  out += in + "]";
  if (c.is_rational()) {
    out += "," + in + "\"weights\": ";
    append_numbers(out, c.weights.data(), c.weights.size());
  }
  out += "\n" + indent + "}";
}

void append_trim_loops(std::string& out, const std::vector<engine::TrimLoop>& loops) {
  out += ",\n      \"trim_loops\": [";
  for (std::size_t l = 0; l < loops.size(); ++l) {
    out += l == 0 ? "\n        {\"curves\": [" : ",\n        {\"curves\": [";
    for (std::size_t c = 0; c < loops[l].curves.size(); ++c) {
      const engine::TrimCurve& curve = loops[l].curves[c];
      out += c == 0 ? "\n          {\"uv\":\n" : ",\n          {\"uv\":\n";
      append_curve(out, curve.uv, "            ", false);
      if (curve.edge) {
        out += ",\n           \"edge\":\n";
        append_curve(out, *curve.edge, "            ", false);
      }
      out += "}";
    }
    out += "\n        ]}";
  }
  out += "\n      ]";
}

void append_surface(std::string& out, const engine::NurbsSurface& s) {
  out += "    {\n      \"name\": ";
  append_string(out, s.name);
  out += ",\n      \"degree\": [" + std::to_string(s.degree_u) + ", " + std::to_string(s.degree_v) +
         "],";
  out += "\n      \"knots_u\": ";
  append_numbers(out, s.knots_u.data(), s.knots_u.size());
  out += ",\n      \"knots_v\": ";
  append_numbers(out, s.knots_v.data(), s.knots_v.size());
  out += ",\n      \"control_points\": [";
  for (int i = 0; i < s.count_u; ++i) {
    out += i == 0 ? "\n        [" : ",\n        [";
    for (int j = 0; j < s.count_v; ++j) {
      if (j > 0) out += ", ";
      append_point(out, s.point(i, j), 3);
    }
    out += ']';
  }
  out += "\n      ]";
  if (s.is_rational()) {
    out += ",\n      \"weights\": [";
    for (int i = 0; i < s.count_u; ++i) {
      out += i == 0 ? "\n        " : ",\n        ";
      append_numbers(out, s.weights.data() + static_cast<std::size_t>(i) * s.count_v,
                     static_cast<std::size_t>(s.count_v));
    }
    out += "\n      ]";
  }
  if (s.reversed) out += ",\n      \"reversed\": true";
  if (s.is_trimmed()) append_trim_loops(out, s.trim_loops);
  out += "\n    }";
}

}  // namespace

engine::Model parse_model(std::string_view text, const std::string& file_label) {
  json document;
  try {
    document = json::parse(text.begin(), text.end());
  } catch (const json::parse_error& error) {
    throw InputError(file_label, syntax_message(text, error));
  } catch (const json::exception& error) {
    // out_of_range 406: a literal such as 1e999 that no double holds (no position available).
    std::string what = error.what();
    what = what.substr(what.find(']') + 2);
    throw InputError(file_label, "invalid JSON: " + text_detail::printable(what) +
                                     " (numbers must fit a double)");
  }
  EntityReader top(file_label, "");
  if (!document.is_object()) {
    top.fail("", "expected a JSON object with \"nurbsreg_model\": 1 at the top level, got " +
                     describe(document));
  }
  const auto version = document.find("nurbsreg_model");
  if (version == document.end()) {
    top.fail("nurbsreg_model", "missing: not a nurbsreg model (expected \"nurbsreg_model\": " +
                                   std::to_string(kModelFormatVersion) + " at the top level)");
  }
  const int v = top.integer(*version, "nurbsreg_model");
  if (v != kModelFormatVersion) {
    top.fail("nurbsreg_model", "unsupported format version " + std::to_string(v) +
                                   " (this build reads version " +
                                   std::to_string(kModelFormatVersion) + ")");
  }

  engine::Model model;
  if (const json* units = optional(document, "units")) {
    if (!units->is_string() || units->get<std::string>().empty()) {
      top.fail("units", "expected a non-empty string such as \"mm\", got " + describe(*units));
    }
    model.units = units->get<std::string>();
  }
  if (const json* surfaces = optional(document, "surfaces")) {
    top.array(*surfaces, "surfaces");
    model.surfaces.reserve(surfaces->size());
    for (std::size_t i = 0; i < surfaces->size(); ++i) {
      model.surfaces.push_back(read_surface(file_label, i, (*surfaces)[i]));
    }
  }
  if (const json* curves = optional(document, "curves")) {
    top.array(*curves, "curves");
    model.curves.reserve(curves->size());
    for (std::size_t i = 0; i < curves->size(); ++i) {
      model.curves.push_back(read_curve(file_label, i, (*curves)[i]));
    }
  }
  if (const json* skipped = optional(document, "skipped_faces"))
    model.skipped_faces = read_skipped_faces(top, *skipped);
  // The reader checked shapes; the engine's validate() owns the geometric rules (finite values,
  // weights > 0, knots), so the two can never disagree about what a valid model is.
  if (auto error = model.validate()) throw InputError(file_label, *error);
  // Valid, but also within what the exact projection can represent and what one model may
  // cost (input_ranges.hpp, resource_limits.hpp).
  detail::check_model_ranges(model, file_label);
  detail::check_model_size(model, file_label);
  return model;
}

engine::Model read_model_json(const std::string& path) {
  const std::string text = text_detail::read_text_file(path);
  return parse_model(text, path);
}

std::string model_to_json(const engine::Model& model) {
  std::string out;
  out += "{\n  \"nurbsreg_model\": " + std::to_string(kModelFormatVersion) + ",\n  \"units\": ";
  append_string(out, model.units);
  if (!model.surfaces.empty()) {
    out += ",\n  \"surfaces\": [\n";
    for (std::size_t i = 0; i < model.surfaces.size(); ++i) {
      if (i > 0) out += ",\n";
      append_surface(out, model.surfaces[i]);
    }
    out += "\n  ]";
  }
  if (!model.curves.empty()) {
    out += ",\n  \"curves\": [\n";
    for (std::size_t i = 0; i < model.curves.size(); ++i) {
      if (i > 0) out += ",\n";
      append_curve(out, model.curves[i], "    ", true);
    }
    out += "\n  ]";
  }
  if (!model.skipped_faces.empty()) {
    out += ",\n  \"skipped_faces\": [";
    for (std::size_t i = 0; i < model.skipped_faces.size(); ++i) {
      out += i == 0 ? "\n    {\"face\": " : ",\n    {\"face\": ";
      out += std::to_string(model.skipped_faces[i].face) + ", \"reason\": ";
      append_string(out, model.skipped_faces[i].reason);
      out += "}";
    }
    out += "\n  ]";
  }
  out += "\n}\n";
  return out;
}

void write_model(const std::string& path, const engine::Model& model) {
  // JSON has no NaN or infinity, and a file we cannot read back would only fail later.
  if (auto error = model.validate())
    throw OutputError(path, "refusing to write an invalid model: " + *error);
  const std::string text = model_to_json(model);
  write_atomically(path, [&](std::ostream& out) {
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
  });
}

}  // namespace nurbsreg::io
