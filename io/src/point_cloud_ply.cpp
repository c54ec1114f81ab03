// PLY reader (Greg Turk's format, as documented by Paul Bourke, "PLY - Polygon File Format"):
// ascii, binary_little_endian and binary_big_endian; the `vertex` element's x, y, z of any
// scalar type. Other properties (lists included) and other elements are skipped, which covers
// the Stanford range scans (`obj_info` header lines, a `range_grid` element of lists).
//
// Our own reader rather than PCL's: PCL's PLY parser aborts or misreads on some valid files
// (list properties in the vertex element, obj_info) and gives poor error messages.
#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cstring>
#include <optional>
#include <vector>

#include "nurbsreg/io/resource_limits.hpp"
#include "point_cloud_detail.hpp"

namespace nurbsreg::io::detail {
namespace {

enum class Scalar { int8, uint8, int16, uint16, int32, uint32, float32, float64 };

std::optional<Scalar> scalar_from_name(std::string_view name) {
  if (name == "char" || name == "int8") return Scalar::int8;
  if (name == "uchar" || name == "uint8") return Scalar::uint8;
  if (name == "short" || name == "int16") return Scalar::int16;
  if (name == "ushort" || name == "uint16") return Scalar::uint16;
  if (name == "int" || name == "int32") return Scalar::int32;
  if (name == "uint" || name == "uint32") return Scalar::uint32;
  if (name == "float" || name == "float32") return Scalar::float32;
  if (name == "double" || name == "float64") return Scalar::float64;
  return std::nullopt;
}

std::size_t size_of(Scalar s) {
  switch (s) {
    case Scalar::int8:
    case Scalar::uint8:
      return 1;
    case Scalar::int16:
    case Scalar::uint16:
      return 2;
    case Scalar::int32:
    case Scalar::uint32:
    case Scalar::float32:
      return 4;
    case Scalar::float64:
      return 8;
  }
  return 0;
}

template <class T>
T load(const unsigned char* p, bool swap) {
  std::array<unsigned char, sizeof(T)> bytes;
  std::memcpy(bytes.data(), p, sizeof(T));
  if (swap) std::reverse(bytes.begin(), bytes.end());
  return std::bit_cast<T>(bytes);
}

double load_scalar(const unsigned char* p, Scalar s, bool swap) {
  switch (s) {
    case Scalar::int8:
      return load<std::int8_t>(p, false);
    case Scalar::uint8:
      return load<std::uint8_t>(p, false);
    case Scalar::int16:
      return load<std::int16_t>(p, swap);
    case Scalar::uint16:
      return load<std::uint16_t>(p, swap);
    case Scalar::int32:
      return load<std::int32_t>(p, swap);
    case Scalar::uint32:
      return load<std::uint32_t>(p, swap);
    case Scalar::float32:
      return load<float>(p, swap);
    case Scalar::float64:
      return load<double>(p, swap);
  }
  return 0.0;
}

struct Property {
  std::string name;
  Scalar type = Scalar::float32;
  bool is_list = false;
  Scalar count_type = Scalar::uint8;  // lists only
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
};

enum class Format { ascii, binary_le, binary_be };

struct Header {
  Format format = Format::ascii;
  std::vector<Element> elements;
  std::size_t data_offset = 0;
  std::size_t lines = 0;  // header lines, for ascii line numbers
};

// A whole token as a non-negative integer (counts and list lengths).
bool parse_count(std::string_view token, std::uint64_t& value) {
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && end == token.data() + token.size() && !token.empty();
}

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r'))
      ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r')
      ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

Header parse_header(const std::string& path, const std::string& data) {
  Header header;
  std::size_t pos = 0;
  bool have_format = false;
  while (true) {
    const std::size_t eol = data.find('\n', pos);
    if (eol == std::string::npos) throw InputError(path, "PLY header has no end_header line");
    const std::string_view line(data.data() + pos, eol - pos);
    pos = eol + 1;
    ++header.lines;
    const auto fail = [&](const std::string& what) {
      return InputError(path, "line " + std::to_string(header.lines) + ": " + what);
    };
    const std::vector<std::string_view> words = split_words(line);
    if (header.lines == 1) {
      if (words.size() != 1 || words[0] != "ply") throw fail("not a PLY file (no 'ply' magic)");
      continue;
    }
    if (words.empty()) continue;
    const std::string_view key = words[0];
    if (key == "comment" || key == "obj_info") continue;
    if (key == "end_header") break;
    if (key == "format") {
      if (words.size() != 3) throw fail("expected 'format <type> 1.0'");
      if (words[1] == "ascii") {
        header.format = Format::ascii;
      } else if (words[1] == "binary_little_endian") {
        header.format = Format::binary_le;
      } else if (words[1] == "binary_big_endian") {
        header.format = Format::binary_be;
      } else {
        throw fail("unknown format " + quote(words[1]));
      }
      have_format = true;
    } else if (key == "element") {
      // An integer token, parsed as one: a count such as 1e30 went through a double before,
      // and casting that to an integer is undefined behaviour.
      std::uint64_t count = 0;
      if (words.size() != 3 || !parse_count(words[2], count)) {
        throw fail("expected 'element <name> <count>' with a non-negative integer count, got " +
                   (words.size() == 3 ? quote(words[2]) : std::string("something else")));
      }
      header.elements.push_back(Element{std::string(words[1]), count, {}});
    } else if (key == "property") {
      if (header.elements.empty()) throw fail("property before any element");
      Property property;
      if (words.size() == 5 && words[1] == "list") {
        const auto count_type = scalar_from_name(words[2]);
        const auto item_type = scalar_from_name(words[3]);
        if (!count_type || !item_type) throw fail("unknown list property type");
        if (*count_type == Scalar::float32 || *count_type == Scalar::float64) {
          throw fail("list count type must be an integer type");
        }
        property = Property{std::string(words[4]), *item_type, true, *count_type};
      } else if (words.size() == 3) {
        const auto type = scalar_from_name(words[1]);
        if (!type) throw fail("unknown property type " + quote(words[1]));
        property = Property{std::string(words[2]), *type, false, Scalar::uint8};
      } else {
        throw fail("expected 'property <type> <name>' or 'property list <type> <type> <name>'");
      }
      header.elements.back().properties.push_back(std::move(property));
    } else {
      throw fail("unknown header keyword " + quote(key));
    }
  }
  if (!have_format) throw InputError(path, "PLY header has no format line");
  header.data_offset = pos;
  return header;
}

struct VertexLayout {
  std::size_t element = 0;                // index of `vertex` in header.elements
  std::array<std::size_t, 3> property{};  // indices of x, y, z among its properties
};

VertexLayout find_vertex(const std::string& path, const Header& header) {
  VertexLayout layout;
  const auto it = std::find_if(header.elements.begin(), header.elements.end(),
                               [](const Element& e) { return e.name == "vertex"; });
  if (it == header.elements.end()) throw InputError(path, "PLY file has no 'vertex' element");
  layout.element = static_cast<std::size_t>(it - header.elements.begin());
  for (int axis = 0; axis < 3; ++axis) {
    const std::string name(1, static_cast<char>('x' + axis));
    const auto p = std::find_if(it->properties.begin(), it->properties.end(),
                                [&](const Property& q) { return q.name == name; });
    if (p == it->properties.end()) {
      throw InputError(path, "PLY element 'vertex' has no property " + text_detail::quote(name));
    }
    if (p->is_list)
      throw InputError(path, "PLY vertex property " + text_detail::quote(name) + " is a list");
    layout.property[axis] = static_cast<std::size_t>(p - it->properties.begin());
  }
  return layout;
}

// ---- ascii ---------------------------------------------------------------------------------

class TokenStream {
 public:
  TokenStream(const std::string& data, std::size_t offset, std::size_t line)
      : p_(data.data() + offset), end_(data.data() + data.size()), line_(line + 1) {}

  bool next(std::string_view& token) {
    while (p_ != end_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\r' || *p_ == '\n')) {
      if (*p_ == '\n') ++line_;
      ++p_;
    }
    if (p_ == end_) return false;
    const char* start = p_;
    while (p_ != end_ && *p_ != ' ' && *p_ != '\t' && *p_ != '\r' && *p_ != '\n')
      ++p_;
    token = std::string_view(start, static_cast<std::size_t>(p_ - start));
    return true;
  }
  std::size_t line() const { return line_; }

 private:
  const char* p_;
  const char* end_;
  std::size_t line_;
};

void read_ascii(const std::string& path, const std::string& data, const Header& header,
                const VertexLayout& layout, PointCloud& cloud) {
  const std::uint64_t max_points = resource_limits().max_points;
  TokenStream tokens(data, header.data_offset, header.lines);
  for (std::size_t e = 0; e <= layout.element; ++e) {
    const Element& element = header.elements[e];
    const bool is_vertex = e == layout.element;
    if (element.properties.empty()) continue;  // no data at all, whatever its count
    if (is_vertex) {
      // Each ascii vertex takes at least 6 bytes ("0 0 0\n"): a bogus count cannot make us
      // reserve more than the file could hold.
      const std::uint64_t most = std::min<std::uint64_t>(element.count, data.size() / 6 + 1);
      cloud.points.reserve(most);
      cloud.source_index.reserve(most);
    }
    for (std::uint64_t i = 0; i < element.count; ++i) {
      std::array<double, 3> xyz{};
      for (std::size_t k = 0; k < element.properties.size(); ++k) {
        const Property& property = element.properties[k];
        std::string_view token;
        const auto fail = [&](const std::string& what) {
          return InputError(path, "line " + std::to_string(tokens.line()) + ": " + what);
        };
        const auto need = [&]() {
          if (!tokens.next(token)) {
            throw InputError(path, "unexpected end of data in element " +
                                       text_detail::quote(element.name) + " " + std::to_string(i) +
                                       " of " + std::to_string(element.count) +
                                       " (file truncated?)");
          }
        };
        need();
        if (property.is_list) {
          std::uint64_t length = 0;
          if (!parse_count(token, length)) {
            throw fail("property " + text_detail::quote(property.name) +
                       ": list length is not a non-negative integer: " + quote(token));
          }
          for (; length > 0; --length)  // each item needs a token: ends at the data's end
            need();
          continue;
        }
        double value = 0.0;
        if (!parse_number(token, value)) {
          throw fail("property " + text_detail::quote(property.name) + ": " +
                     text_detail::bad_number(token));
        }
        if (is_vertex) {
          // A float property holds a float whatever the encoding (binary files agree).
          if (property.type == Scalar::float32) value = static_cast<float>(value);
          for (int axis = 0; axis < 3; ++axis) {
            if (layout.property[axis] == k) xyz[axis] = value;
          }
        }
      }
      if (is_vertex) {
        if (cloud.total == max_points) throw too_many_points(path, max_points);
        add_point(cloud, xyz[0], xyz[1], xyz[2]);
      }
    }
  }
}

// ---- binary --------------------------------------------------------------------------------

void read_binary(const std::string& path, const std::string& data, const Header& header,
                 const VertexLayout& layout, PointCloud& cloud) {
  const std::uint64_t max_points = resource_limits().max_points;
  const bool swap =
      (header.format == Format::binary_be) != (std::endian::native == std::endian::big);
  const auto* const begin = reinterpret_cast<const unsigned char*>(data.data());
  const auto* p = begin + header.data_offset;
  const auto* const end = begin + data.size();
  const auto truncated = [&](const Element& element, std::uint64_t i) {
    return InputError(path, "binary data ends in element " + text_detail::quote(element.name) +
                                " " + std::to_string(i) + " of " + std::to_string(element.count) +
                                " (file truncated?)");
  };

  for (std::size_t e = 0; e <= layout.element; ++e) {
    const Element& element = header.elements[e];
    const bool is_vertex = e == layout.element;
    const bool has_list = std::any_of(element.properties.begin(), element.properties.end(),
                                      [](const Property& q) { return q.is_list; });
    std::vector<std::size_t> offset(element.properties.size());
    std::size_t stride = 0;
    for (std::size_t k = 0; k < element.properties.size(); ++k) {
      offset[k] = stride;
      stride += size_of(element.properties[k].type);
    }
    if (!has_list) {
      // Fixed-size records: check the whole block once, then read without per-field checks.
      const auto available = static_cast<std::uint64_t>(end - p);
      if (stride != 0 && available / stride < element.count) {
        throw truncated(element, available / stride);
      }
      if (!is_vertex) {
        p += element.count * stride;
        continue;
      }
      if (element.count > max_points) throw too_many_points(path, max_points);
      cloud.points.reserve(element.count);  // <= the file's bytes / stride, checked above
      cloud.source_index.reserve(element.count);
      std::array<std::size_t, 3> at{};
      std::array<Scalar, 3> type{};
      for (int axis = 0; axis < 3; ++axis) {
        at[axis] = offset[layout.property[axis]];
        type[axis] = element.properties[layout.property[axis]].type;
      }
      for (std::uint64_t i = 0; i < element.count; ++i, p += stride) {
        add_point(cloud, load_scalar(p + at[0], type[0], swap),
                  load_scalar(p + at[1], type[1], swap), load_scalar(p + at[2], type[2], swap));
      }
      continue;
    }
    // Records with lists: walk property by property with bounds checks.
    for (std::uint64_t i = 0; i < element.count; ++i) {
      std::array<double, 3> xyz{};
      for (std::size_t k = 0; k < element.properties.size(); ++k) {
        const Property& property = element.properties[k];
        if (property.is_list) {
          const std::size_t count_size = size_of(property.count_type);
          if (static_cast<std::size_t>(end - p) < count_size) throw truncated(element, i);
          const double n = load_scalar(p, property.count_type, swap);
          p += count_size;
          if (n < 0)
            throw InputError(path,
                             "negative list length in element " + text_detail::quote(element.name));
          const auto bytes = static_cast<std::uint64_t>(n) * size_of(property.type);
          if (static_cast<std::uint64_t>(end - p) < bytes) throw truncated(element, i);
          p += bytes;
        } else {
          const std::size_t size = size_of(property.type);
          if (static_cast<std::size_t>(end - p) < size) throw truncated(element, i);
          if (is_vertex) {
            for (int axis = 0; axis < 3; ++axis) {
              if (layout.property[axis] == k) xyz[axis] = load_scalar(p, property.type, swap);
            }
          }
          p += size;
        }
      }
      if (is_vertex) {
        if (cloud.total == max_points) throw too_many_points(path, max_points);
        add_point(cloud, xyz[0], xyz[1], xyz[2]);
      }
    }
  }
}

}  // namespace

void read_ply(const std::string& path, PointCloud& cloud) {
  parse_ply(path, read_text_file(path), cloud);
}

void parse_ply(const std::string& path, const std::string& data, PointCloud& cloud) {
  const Header header = parse_header(path, data);
  const VertexLayout layout = find_vertex(path, header);
  if (header.format == Format::ascii) {
    read_ascii(path, data, header, layout, cloud);
  } else {
    read_binary(path, data, header, layout, cloud);
  }
}

}  // namespace nurbsreg::io::detail
