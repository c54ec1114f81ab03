#include "nurbsreg/io/iges_reader.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <vector>

#include "nurbsreg/io/errors.hpp"
#include "text_io.hpp"

namespace nurbsreg::io {
namespace {

// IGES 5.3 §2.2: 80-column records; column 73 names the section, 74-80 hold its sequence number.
struct Record {
  std::string_view text;  // columns 1-72
  std::size_t line = 0;   // line number in the file, for messages
};

struct Sections {
  std::vector<Record> global;
  std::vector<Record> directory;
  std::vector<Record> parameter;
};

Sections split_sections(std::string_view text, const std::string& file) {
  Sections sections;
  std::size_t start = 0;
  std::size_t line = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    std::string_view record = text.substr(start, end - start);
    start = end + 1;
    ++line;
    if (!record.empty() && record.back() == '\r') record.remove_suffix(1);
    if (record.find_first_not_of(' ') == std::string_view::npos) continue;
    if (record.size() < 73) {
      if (sections.global.empty() && sections.directory.empty()) {
        throw InputError(file, "line " + std::to_string(line) +
                                   ": not a fixed-format IGES file (80-column records with a "
                                   "section letter in column 73 expected)");
      }
      throw InputError(file, "line " + std::to_string(line) +
                                 ": record shorter than 73 columns (no section letter)");
    }
    const Record r{record.substr(0, 72), line};
    switch (record[72]) {
      case 'S':
      case 'T':
        break;
      case 'G':
        sections.global.push_back(r);
        break;
      case 'D':
        sections.directory.push_back(r);
        break;
      case 'P':
        sections.parameter.push_back(r);
        break;
      case 'C':
        throw InputError(file, "compressed ASCII IGES is not supported (convert to fixed format)");
      default:
        throw InputError(file, "line " + std::to_string(line) + ": unknown section letter '" +
                                   std::string(1, record[72]) + "' in column 73");
    }
  }
  if (sections.directory.empty()) {
    throw InputError(file, "not an IGES file: no Directory Entry section (column 73 = 'D')");
  }
  return sections;
}

// Free-format parameters (§2.2.3): fields separated by the parameter delimiter, ended by the
// record delimiter; Hollerith strings `nH...` may contain either delimiter.
std::vector<std::string> split_fields(std::string_view data, char field_delimiter,
                                      char record_delimiter) {
  std::vector<std::string> fields;
  std::string current;
  std::size_t i = 0;
  while (i < data.size()) {
    const char c = data[i];
    if (c == field_delimiter || c == record_delimiter) {
      fields.push_back(current);
      current.clear();
      if (c == record_delimiter) return fields;
      ++i;
      continue;
    }
    // A Hollerith count: digits then 'H', with only blanks before it in this field.
    if (std::isdigit(static_cast<unsigned char>(c)) &&
        current.find_first_not_of(' ') == std::string::npos) {
      std::size_t j = i;
      while (j < data.size() && std::isdigit(static_cast<unsigned char>(data[j])))
        ++j;
      if (j < data.size() && data[j] == 'H') {
        std::size_t n = 0;
        std::from_chars(data.data() + i, data.data() + j, n);
        current = std::string(data.substr(j + 1, n));
        i = std::min(data.size(), j + 1 + n);
        continue;
      }
    }
    current += c;
    ++i;
  }
  fields.push_back(current);
  return fields;
}

std::string trim(std::string_view s) {
  const std::size_t a = s.find_first_not_of(' ');
  if (a == std::string_view::npos) return {};
  const std::size_t b = s.find_last_not_of(' ');
  return std::string(s.substr(a, b - a + 1));
}

// IGES reals may use a Fortran exponent letter (1.0D0); an empty field means the default 0.
bool parse_real(std::string field, double& value) {
  field = trim(field);
  if (field.empty()) {
    value = 0.0;
    return true;
  }
  std::replace(field.begin(), field.end(), 'D', 'E');
  std::replace(field.begin(), field.end(), 'd', 'e');
  return text_detail::parse_number(field, value);
}

struct Global {
  char field_delimiter = ',';
  char record_delimiter = ';';
  std::string units = engine::Model().units;
};

// The delimiters (fields 1-2, each empty or `1H<c>`) and the unit flag and name (fields 14-15).
Global read_global(const std::vector<Record>& records, const std::string& file) {
  std::string data;
  for (const Record& r : records)
    data += r.text;
  Global g;
  std::size_t pos = 0;
  for (char* delimiter : {&g.field_delimiter, &g.record_delimiter}) {
    if (data.compare(pos, 2, "1H") == 0 && pos + 2 < data.size()) {
      *delimiter = data[pos + 2];
      pos += 3;
    }
    // Skip to just past the field delimiter that ends this field.
    const std::size_t next = data.find(g.field_delimiter, pos);
    if (next == std::string::npos) return g;
    pos = next + 1;
  }
  // Fields 3.. (split_fields starts counting at field 3 here).
  const std::vector<std::string> fields =
      split_fields(std::string_view(data).substr(pos), g.field_delimiter, g.record_delimiter);
  if (fields.size() < 13) return g;
  double flag = 0;
  if (!parse_real(fields[11], flag)) {
    throw InputError(
        file, "Global section: field 14 (units flag) is not a number: \"" + fields[11] + "\"");
  }
  static const char* kUnits[] = {"",  "inch", "mm",  "",   "foot", "mile",
                                 "m", "km",   "mil", "um", "cm",   "microinch"};
  const int f = static_cast<int>(flag);
  if (f == 3) {
    std::string name = trim(fields[12]);
    for (char& ch : name)
      ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (!name.empty()) g.units = name;
  } else if (f >= 1 && f <= 11 && kUnits[f][0] != '\0') {
    g.units = kUnits[f];
  }
  return g;
}

// One directory entry (§2.2.4): two records of ten 8-column fields.
struct Entry {
  int type = 0;
  int parameter_start = 0;  // sequence number of the first parameter record
  int transformation = 0;   // DE sequence number of a type-124 matrix, or 0
  int parameter_lines = 0;
  int form = 0;
  std::string label;  // entity label, columns 57-64 of the second record
  std::size_t line = 0;
};

int field_int(std::string_view record, int index, const std::string& file, std::size_t line) {
  const std::string f = trim(record.substr(static_cast<std::size_t>(index) * 8, 8));
  if (f.empty()) return 0;
  int value = 0;
  const auto r = std::from_chars(f.data(), f.data() + f.size(), value);
  if (r.ec != std::errc() || r.ptr != f.data() + f.size()) {
    throw InputError(file, "line " + std::to_string(line) + ": directory field " +
                               std::to_string(index + 1) + " is not an integer: \"" + f + "\"");
  }
  return value;
}

std::vector<Entry> read_directory(const std::vector<Record>& records, const std::string& file) {
  if (records.size() % 2 != 0) {
    throw InputError(file, "line " + std::to_string(records.back().line) +
                               ": Directory Entry section has an odd number of records");
  }
  std::vector<Entry> entries(records.size() / 2);
  for (std::size_t k = 0; k < entries.size(); ++k) {
    const Record& a = records[2 * k];
    const Record& b = records[2 * k + 1];
    Entry& e = entries[k];
    e.line = a.line;
    e.type = field_int(a.text, 0, file, a.line);
    e.parameter_start = field_int(a.text, 1, file, a.line);
    e.transformation = field_int(a.text, 6, file, a.line);
    e.parameter_lines = field_int(b.text, 3, file, b.line);
    e.form = field_int(b.text, 4, file, b.line);
    e.label = trim(b.text.substr(56, 8));
  }
  return entries;
}

class IgesFile {
 public:
  IgesFile(std::string_view text, const std::string& file) : file_(file) {
    const Sections sections = split_sections(text, file);
    global_ = read_global(sections.global, file);
    entries_ = read_directory(sections.directory, file);
    parameter_ = sections.parameter;
  }

  const std::vector<Entry>& entries() const { return entries_; }
  const Global& global() const { return global_; }
  const std::string& file() const { return file_; }

  // "DE 7 (type 128)": the entity's directory sequence number, as other IGES tools print it.
  static std::string label(std::size_t index, int type) {
    return "DE " + std::to_string(2 * index + 1) + " (type " + std::to_string(type) + ")";
  }

  // The entity's parameters after the leading type number (columns 1-64 of its P records).
  std::vector<std::string> parameters(std::size_t index) const {
    const Entry& e = entries_[index];
    const std::string where = label(index, e.type);
    if (e.parameter_start < 1 || e.parameter_lines < 1 ||
        static_cast<std::size_t>(e.parameter_start - 1 + e.parameter_lines) > parameter_.size()) {
      throw InputError(file_, where + ": parameter data pointer " +
                                  std::to_string(e.parameter_start) + " (+" +
                                  std::to_string(e.parameter_lines) +
                                  " lines) is outside the Parameter Data section");
    }
    std::string data;
    for (int k = 0; k < e.parameter_lines; ++k) {
      data += parameter_[static_cast<std::size_t>(e.parameter_start - 1 + k)].text.substr(0, 64);
    }
    std::vector<std::string> fields =
        split_fields(data, global_.field_delimiter, global_.record_delimiter);
    double type = 0;
    if (fields.empty() || !parse_real(fields[0], type) || static_cast<int>(type) != e.type) {
      throw InputError(file_, where + ": parameter data starts with \"" +
                                  (fields.empty() ? std::string() : trim(fields[0])) +
                                  "\", not the entity type " + std::to_string(e.type));
    }
    fields.erase(fields.begin());
    return fields;
  }

  // Index of the entry with directory sequence number `de` (odd, 1-based).
  std::size_t index_of(int de, const std::string& from) const {
    if (de < 1 || de % 2 == 0 || static_cast<std::size_t>(de / 2) >= entries_.size()) {
      throw InputError(file_,
                       from + ": directory pointer " + std::to_string(de) + " is not an entity");
    }
    return static_cast<std::size_t>(de / 2);
  }

 private:
  const std::string& file_;
  Global global_;
  std::vector<Entry> entries_;
  std::vector<Record> parameter_;
};

// Field reader for one entity's parameters, naming the entity and the field in errors.
class Fields {
 public:
  Fields(const IgesFile& iges, std::string label, std::vector<std::string> fields)
      : iges_(iges), label_(std::move(label)), fields_(std::move(fields)) {}

  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw InputError(iges_.file(), label_ + ": " + field + ": " + what);
  }
  double real(std::size_t k, const std::string& field) const {
    if (k >= fields_.size()) fail(field, "missing (the parameter data ends early)");
    double value = 0.0;
    if (!parse_real(fields_[k], value)) fail(field, "\"" + trim(fields_[k]) + "\" is not a number");
    return value;
  }
  int integer(std::size_t k, const std::string& field) const {
    const double x = real(k, field);
    if (x != std::floor(x) || std::abs(x) > 1e8)
      fail(field, "expected an integer, got " + trim(fields_[k]));
    return static_cast<int>(x);
  }
  const std::string& label() const { return label_; }
  std::size_t size() const { return fields_.size(); }

 private:
  const IgesFile& iges_;
  std::string label_;
  std::vector<std::string> fields_;
};

// The composed transformation of a chain of type-124 entities (§4.21): x' = R x + T.
Eigen::Matrix<double, 3, 4> transformation(const IgesFile& iges, int de, const std::string& from) {
  Eigen::Matrix<double, 3, 4> total = Eigen::Matrix<double, 3, 4>::Identity();
  int guard = 0;
  while (de != 0) {
    const std::size_t index = iges.index_of(de, from);
    const Entry& e = iges.entries()[index];
    const std::string label = IgesFile::label(index, e.type);
    if (e.type != 124)
      throw InputError(iges.file(),
                       from + ": transformation pointer " + label + " is not type 124");
    if (++guard > 64)
      throw InputError(iges.file(), from + ": transformation chain does not end (cycle?)");
    const Fields f(iges, label, iges.parameters(index));
    Eigen::Matrix<double, 3, 4> m;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c)
        m(r, c) =
            f.real(static_cast<std::size_t>(4 * r + c), "R/T[" + std::to_string(4 * r + c) + "]");
    }
    // The entity's own matrix applies first, then the one it points to (§3.2.2).
    Eigen::Matrix<double, 3, 4> composed;
    composed.leftCols<3>() = m.leftCols<3>() * total.leftCols<3>();
    composed.col(3) = m.leftCols<3>() * total.col(3) + m.col(3);
    total = composed;
    de = e.transformation;
  }
  return total;
}

// Type 128, Rational B-Spline Surface (§4.24): K1 K2 M1 M2 PROP1..5, knots S(-M1..N1+M1),
// T(-M2..N2+M2), weights and points with the first index fastest, then U0 U1 V0 V1.
engine::NurbsSurface read_surface(const IgesFile& iges, std::size_t index,
                                  IgesImportReport& report) {
  const Entry& e = iges.entries()[index];
  const Fields f(iges, IgesFile::label(index, e.type), iges.parameters(index));
  engine::NurbsSurface s;
  s.name = e.label.empty() ? "DE " + std::to_string(2 * index + 1) : e.label;
  const int k1 = f.integer(0, "K1");
  const int k2 = f.integer(1, "K2");
  s.degree_u = f.integer(2, "M1 (degree u)");
  s.degree_v = f.integer(3, "M2 (degree v)");
  const bool polynomial = f.integer(6, "PROP3") == 1;
  if (s.degree_u < 1 || s.degree_u > engine::kMaxDegree || s.degree_v < 1 ||
      s.degree_v > engine::kMaxDegree) {
    f.fail("M1, M2 (degrees)", "(" + std::to_string(s.degree_u) + ", " +
                                   std::to_string(s.degree_v) + ") outside 1.." +
                                   std::to_string(engine::kMaxDegree));
  }
  if (k1 < s.degree_u || k2 < s.degree_v || k1 > 1'000'000 || k2 > 1'000'000) {
    f.fail("K1, K2", "upper indices (" + std::to_string(k1) + ", " + std::to_string(k2) +
                         ") need at least degree + 1 control points in each direction");
  }
  s.count_u = k1 + 1;
  s.count_v = k2 + 1;
  // Sizes implied by K1, K2 are checked against the parameters actually present before
  // anything is allocated, so a corrupt header cannot request terabytes.
  const std::size_t n_points =
      static_cast<std::size_t>(s.count_u) * static_cast<std::size_t>(s.count_v);
  const std::size_t needed = 9 + static_cast<std::size_t>(s.count_u + s.degree_u + 1) +
                             static_cast<std::size_t>(s.count_v + s.degree_v + 1) + 4 * n_points;
  if (f.size() < needed) {
    f.fail("K1, K2", "(" + std::to_string(k1) + ", " + std::to_string(k2) + ") imply " +
                         std::to_string(needed) + " parameters, the entity has " +
                         std::to_string(f.size()) + " (the parameter data ends early)");
  }
  std::size_t k = 9;
  for (int a = 0; a < s.count_u + s.degree_u + 1; ++a)
    s.knots_u.push_back(f.real(k++, "knots_u[" + std::to_string(a) + "]"));
  for (int a = 0; a < s.count_v + s.degree_v + 1; ++a)
    s.knots_v.push_back(f.real(k++, "knots_v[" + std::to_string(a) + "]"));
  const std::size_t n = static_cast<std::size_t>(s.count_u) * s.count_v;
  s.weights.resize(n);
  s.control_points.resize(n);
  // IGES order: W(0,0), W(1,0), ..., W(K1,0), W(0,1), ...; nurbsreg: [i * count_v + j].
  for (int j = 0; j < s.count_v; ++j) {
    for (int i = 0; i < s.count_u; ++i) {
      s.weights[static_cast<std::size_t>(i) * s.count_v + j] =
          f.real(k++, "weights[" + std::to_string(i) + "][" + std::to_string(j) + "]");
    }
  }
  for (int j = 0; j < s.count_v; ++j) {
    for (int i = 0; i < s.count_u; ++i) {
      engine::Vec3& p = s.control_points[static_cast<std::size_t>(i) * s.count_v + j];
      const std::string field =
          "control_points[" + std::to_string(i) + "][" + std::to_string(j) + "]";
      for (int c = 0; c < 3; ++c)
        p[c] = f.real(k++, field);
    }
  }
  if (polynomial) s.weights.clear();
  if (e.transformation != 0) {
    const Eigen::Matrix<double, 3, 4> m = transformation(iges, e.transformation, f.label());
    for (engine::Vec3& p : s.control_points)
      p = m.leftCols<3>() * p + m.col(3);
    ++report.transformed;
  }
  if (auto error = s.validate()) throw InputError(iges.file(), f.label() + ": " + *error);
  return s;
}

}  // namespace

engine::Model parse_iges(std::string_view text, const std::string& file_label,
                         IgesImportReport* report_out) {
  const IgesFile iges(text, file_label);
  IgesImportReport report;
  report.entities = iges.entries().size();
  engine::Model model;
  model.units = iges.global().units;
  for (std::size_t index = 0; index < iges.entries().size(); ++index) {
    const int type = iges.entries()[index].type;
    if (type == 128) {
      model.surfaces.push_back(read_surface(iges, index, report));
      ++report.bspline_surfaces;
      if (model.surfaces.back().is_rational()) ++report.rational_surfaces;
    } else if ((type >= 108 && type <= 122 && type != 110 && type != 112 && type != 116) ||
               type == 140 || type == 190 || type == 192 || type == 194 || type == 196 ||
               type == 198) {
      // Plane, ruled, revolved, tabulated, offset and the analytic surfaces of §4.
      ++report.other_surfaces[type];
    }
  }
  if (model.surfaces.empty()) {
    throw InputError(file_label, "no B-spline surfaces (type 128) to import among " +
                                     std::to_string(report.entities) + " entities");
  }
  if (report_out != nullptr) *report_out = std::move(report);
  return model;
}

engine::Model read_iges(const std::string& path, IgesImportReport* report) {
  const std::string text = text_detail::read_text_file(path);
  return parse_iges(text, path, report);
}

}  // namespace nurbsreg::io
