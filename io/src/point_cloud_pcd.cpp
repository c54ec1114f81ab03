// PCD reader (PCL's Point Cloud Data format, v0.5-v0.7), entirely ours.
//
// A header can claim any size, so every count is checked with overflow-safe arithmetic and
// against the bytes the file really has before anything is allocated: nothing a header says
// makes us allocate more than a small multiple of the file's size. PCL's PCDReader is not used:
// it resizes its buffer to POINTS x point_step before looking at the file size (8.6 GB from a
// 102-byte file whose COUNTs wrap), and its binary_compressed decoder lays out `_` fields
// differently from its binary one. The layout rules (PCL's own):
//  - a row is the fields in order, each SIZE x COUNT bytes, no alignment (binary); the same
//    values as text, one row a line (ascii); for binary_compressed, uint32 compressed size,
//    uint32 uncompressed size, then LZF data that decompresses to the fields' planes one after
//    the other (structure of arrays: all x, then all y, ...);
//  - `_` names a padding field: laid out like any other field in every encoding, never read;
//  - COUNT 0 is rejected by name: PCL writes COUNT >= 1, and a zero-width x/y/z would be read
//    from its neighbour's bytes;
//  - ascii bodies hold exactly POINTS rows (POINTS 0 with rows is an error); binary bodies at
//    least POINTS rows (trailing bytes ignored, as PCL does), for POINTS 0 too.
// ASCII numbers go through the project's one number parser (text_io.hpp): PCL would turn a
// bad token into 0 without an error, while we owe the user `line N: ...`.
#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cstring>
#include <limits>

#include "lzf.hpp"
#include "nurbsreg/io/resource_limits.hpp"
#include "point_cloud_detail.hpp"

namespace nurbsreg::io::detail {
namespace {

struct Prescan {
  std::size_t header_end = 0;  // offset of the first body byte
  std::size_t header_lines = 0;
  std::string data_type;  // ascii, binary, binary_compressed
  std::vector<std::string> names;
  std::vector<std::size_t> sizes, counts;
  std::vector<char> types;
  std::uint64_t width = 0, height = 1, points = 0;
  bool have_points = false, have_width = false;
};

std::uint64_t parse_count(const std::string& path, std::size_t line, std::string_view keyword,
                          std::string_view token) {
  std::uint64_t value = 0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec != std::errc() || end != token.data() + token.size()) {
    throw InputError(path, "line " + std::to_string(line) + ": " + std::string(keyword) +
                               ": not a non-negative integer: " + quote(token));
  }
  return value;
}

std::vector<std::string_view> words_of(std::string_view line) {
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

// Reads the header lines up to DATA and checks that they agree with each other, so that the
// sizes used below (and by PCL) are trustworthy.
Prescan prescan_header(const std::string& path, const std::string& data) {
  Prescan h;
  std::size_t pos = 0;
  while (true) {
    if (pos >= data.size()) throw InputError(path, "PCD header has no DATA line");
    std::size_t eol = data.find('\n', pos);
    const bool last = eol == std::string::npos;
    if (last) eol = data.size();
    const std::string_view line(data.data() + pos, eol - pos);
    pos = last ? eol : eol + 1;
    ++h.header_lines;
    const std::vector<std::string_view> words = words_of(line);
    if (words.empty() || words[0].front() == '#') continue;
    const std::string_view key = words[0];
    const std::size_t n = h.header_lines;
    const auto fail = [&](const std::string& what) {
      return InputError(path, "line " + std::to_string(n) + ": " + what);
    };
    if (key == "VERSION" || key == "VIEWPOINT") continue;
    if (key == "FIELDS" || key == "COLUMNS") {
      for (std::size_t i = 1; i < words.size(); ++i)
        h.names.emplace_back(words[i]);
    } else if (key == "SIZE") {
      for (std::size_t i = 1; i < words.size(); ++i) {
        const std::uint64_t size = parse_count(path, n, key, words[i]);
        if (size != 1 && size != 2 && size != 4 && size != 8)
          throw fail("SIZE must be 1, 2, 4 or 8");
        h.sizes.push_back(size);
      }
    } else if (key == "TYPE") {
      for (std::size_t i = 1; i < words.size(); ++i) {
        if (words[i].size() != 1 ||
            std::string_view("FIU").find(words[i][0]) == std::string_view::npos) {
          throw fail("TYPE must be F, I or U, got " + quote(words[i]));
        }
        h.types.push_back(words[i][0]);
      }
    } else if (key == "COUNT") {
      for (std::size_t i = 1; i < words.size(); ++i) {
        h.counts.push_back(parse_count(path, n, key, words[i]));
      }
    } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
      if (words.size() != 2) throw fail(std::string(key) + " takes one number");
      const std::uint64_t value = parse_count(path, n, key, words[1]);
      if (key == "WIDTH") {
        h.width = value;
        h.have_width = true;
      } else if (key == "HEIGHT") {
        h.height = value;
      } else {
        h.points = value;
        h.have_points = true;
      }
    } else if (key == "DATA") {
      if (words.size() != 2 ||
          (words[1] != "ascii" && words[1] != "binary" && words[1] != "binary_compressed")) {
        throw fail("DATA must be ascii, binary or binary_compressed");
      }
      h.data_type = std::string(words[1]);
      h.header_end = pos;
      break;
    } else {
      throw fail("unknown PCD header keyword " + quote(key));
    }
  }
  if (h.names.empty()) throw InputError(path, "PCD header has no FIELDS line");
  if (h.counts.empty()) h.counts.assign(h.names.size(), 1);
  if (h.sizes.size() != h.names.size() || h.types.size() != h.names.size() ||
      h.counts.size() != h.names.size()) {
    throw InputError(path,
                     "PCD header: FIELDS, SIZE, TYPE and COUNT list different numbers of "
                     "fields (" +
                         std::to_string(h.names.size()) + ", " + std::to_string(h.sizes.size()) +
                         ", " + std::to_string(h.types.size()) + ", " +
                         std::to_string(h.counts.size()) + ")");
  }
  for (std::size_t i = 0; i < h.names.size(); ++i) {
    if (h.types[i] == 'F' && h.sizes[i] != 4 && h.sizes[i] != 8) {
      throw InputError(
          path, "PCD field " + text_detail::quote(h.names[i]) + ": TYPE F needs SIZE 4 or 8");
    }
  }
  if (!h.have_width && !h.have_points) throw InputError(path, "PCD header has no WIDTH or POINTS");
  if (!h.have_points) h.points = h.width * h.height;
  if (!h.have_width) {
    h.width = h.points;
    h.height = 1;
  }
  if (h.width > std::numeric_limits<std::uint32_t>::max() ||
      h.height > std::numeric_limits<std::uint32_t>::max() ||
      (h.height != 0 && h.width > std::numeric_limits<std::uint64_t>::max() / h.height) ||
      h.width * h.height != h.points) {
    throw InputError(path, "PCD header: WIDTH x HEIGHT (" + std::to_string(h.width) + " x " +
                               std::to_string(h.height) + ") differs from POINTS (" +
                               std::to_string(h.points) + ")");
  }
  return h;
}

// Refuses bodies that cannot be as large as the header claims, before anything is allocated.
void check_body_size(const std::string& path, const std::string& data, const Prescan& h,
                     std::uint64_t step, std::uint64_t values_per_point) {
  const std::uint64_t available = data.size() - h.header_end;
  const std::uint64_t points = h.points;
  const auto truncated = [&](const std::string& what) {
    return InputError(path, "PCD data is truncated or corrupt: " + what);
  };
  if (h.data_type == "ascii") {
    // Every value takes at least one byte: a bogus POINTS cannot make us allocate more than
    // a few times the file size.
    if (values_per_point != 0 && points > available / values_per_point) {
      throw truncated("POINTS " + std::to_string(points) + " cannot fit in " +
                      std::to_string(available) + " bytes of ascii data");
    }
    return;
  }
  if (step != 0 && points > std::numeric_limits<std::uint64_t>::max() / step) {
    throw truncated("POINTS x point size overflows");
  }
  const std::uint64_t bytes = points * step;
  if (h.data_type == "binary") {
    if (bytes > available) {
      throw truncated("expected " + std::to_string(bytes) + " bytes of binary data (" +
                      std::to_string(points) + " points x " + std::to_string(step) +
                      " bytes), file has " + std::to_string(available));
    }
    return;
  }
  // binary_compressed: uint32 compressed size, uint32 uncompressed size, LZF stream.
  if (available < 8) throw truncated("binary_compressed data has no size header");
  std::uint32_t compressed = 0, uncompressed = 0;
  std::memcpy(&compressed, data.data() + h.header_end, 4);
  std::memcpy(&uncompressed, data.data() + h.header_end + 4, 4);
  if (compressed > available - 8) {
    throw truncated("compressed size " + std::to_string(compressed) + " exceeds the " +
                    std::to_string(available - 8) + " bytes left in the file");
  }
  if (uncompressed != bytes) {
    throw truncated("uncompressed size " + std::to_string(uncompressed) +
                    " differs from POINTS x point size = " + std::to_string(bytes));
  }
  // LZF cannot expand by more than about 100x (a 3-byte back reference copies <= 264 bytes), so
  // a larger claim is corrupt, and refusing it keeps us from allocating for it.
  if (bytes > 100 * static_cast<std::uint64_t>(compressed) + 1024) {
    throw truncated("uncompressed size " + std::to_string(uncompressed) + " is impossible for " +
                    std::to_string(compressed) + " compressed bytes");
  }
}

void read_ascii_body(const std::string& path, const std::string& data, const Prescan& h,
                     PcdData& out) {
  if (h.points == 0) {
    // No rows to hold (and values_per_point may be anything): any content is an error.
    const std::string_view body(data.data() + h.header_end, data.size() - h.header_end);
    if (body.find_first_not_of(" \t\r\n") != std::string_view::npos) {
      throw InputError(
          path, "line " +
                    std::to_string(h.header_lines + 1 +
                                   std::count(body.begin(),
                                              body.begin() + static_cast<std::ptrdiff_t>(
                                                                 body.find_first_not_of(" \t\r\n")),
                                              '\n')) +
                    ": more data than POINTS 0");
    }
    return;
  }
  out.values.resize(h.points * out.values_per_point);
  // A value of a TYPE F SIZE 4 field is a float, as in binary files: round the text to float so
  // that the encoding does not change the coordinates.
  std::vector<char> is_float(out.values_per_point, 0);
  for (const PcdField& f : out.fields) {
    if (f.type == 'F' && f.size == 4) std::fill_n(is_float.begin() + f.first, f.count, 1);
  }
  const char* p = data.data() + h.header_end;
  const char* const end = data.data() + data.size();
  std::size_t line = h.header_lines;
  std::size_t point = 0;
  while (p < end) {
    ++line;
    const char* eol =
        static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)));
    if (eol == nullptr) eol = end;
    const char* q = p;
    p = eol + 1;
    std::size_t k = 0;
    double* row = nullptr;
    while (true) {
      while (q != eol && (*q == ' ' || *q == '\t' || *q == '\r'))
        ++q;
      if (q == eol) break;
      const char* start = q;
      while (q != eol && *q != ' ' && *q != '\t' && *q != '\r')
        ++q;
      const std::string_view token(start, static_cast<std::size_t>(q - start));
      if (row == nullptr) {
        if (point == h.points) {
          throw InputError(path, "line " + std::to_string(line) + ": more data than POINTS " +
                                     std::to_string(h.points));
        }
        row = out.values.data() + point * out.values_per_point;
      }
      if (k == out.values_per_point) break;  // counted below as too many values
      if (!parse_number(token, row[k])) {
        throw InputError(path,
                         "line " + std::to_string(line) + ": " + text_detail::bad_number(token));
      }
      if (is_float[k]) row[k] = static_cast<float>(row[k]);
      ++k;
    }
    if (row == nullptr) continue;  // blank line
    if (k != out.values_per_point || q != eol) {
      throw InputError(path, "line " + std::to_string(line) + ": expected " +
                                 std::to_string(out.values_per_point) + " numbers (FIELDS " +
                                 "with their COUNTs)");
    }
    ++point;
  }
  if (point != h.points) {
    throw InputError(path, "PCD data is truncated: header says " + std::to_string(h.points) +
                               " points, file has " + std::to_string(point));
  }
}

void read_binary_body(const std::string& path, const std::string& data, const Prescan& h,
                      PcdData& out) {
  // check_body_size has bounded points x point_step by the file's bytes.
  const std::size_t bytes = h.points * out.point_step;
  const auto* body = reinterpret_cast<const std::uint8_t*>(data.data()) + h.header_end;
  if (h.data_type == "binary") {
    out.rows.assign(body, body + bytes);
    return;
  }
  std::uint32_t compressed = 0;
  std::memcpy(&compressed, body, 4);
  std::vector<std::uint8_t> planes(bytes);
  if (!lzf_decompress(body + 8, compressed, planes.data(), planes.size())) {
    throw InputError(path, "corrupt binary_compressed data (LZF decompression failed)");
  }
  // Structure of arrays -> rows: field f's plane holds points x (size x count) bytes.
  out.rows.resize(bytes);
  std::size_t plane = 0;
  for (const PcdField& f : out.fields) {
    const std::size_t width = f.size * f.count;
    for (std::size_t i = 0; i < h.points; ++i) {
      std::memcpy(out.rows.data() + i * out.point_step + f.offset,
                  planes.data() + plane + i * width, width);
    }
    plane += width * h.points;
  }
}

template <class T>
T load_native(const std::uint8_t* p) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  return value;
}

}  // namespace

double PcdData::value(std::size_t i, const PcdField& f, std::size_t k) const {
  if (ascii) return values[i * values_per_point + f.first + k];
  const std::uint8_t* p = rows.data() + i * point_step + f.offset + k * f.size;
  switch (f.type) {
    case 'F':
      return f.size == 4 ? load_native<float>(p) : load_native<double>(p);
    case 'I':
      switch (f.size) {
        case 1:
          return load_native<std::int8_t>(p);
        case 2:
          return load_native<std::int16_t>(p);
        case 4:
          return load_native<std::int32_t>(p);
        default:
          return static_cast<double>(load_native<std::int64_t>(p));
      }
    default:
      switch (f.size) {
        case 1:
          return load_native<std::uint8_t>(p);
        case 2:
          return load_native<std::uint16_t>(p);
        case 4:
          return load_native<std::uint32_t>(p);
        default:
          return static_cast<double>(load_native<std::uint64_t>(p));
      }
  }
}

const PcdField* PcdData::find(std::string_view name) const {
  for (const PcdField& f : fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

PcdData read_pcd_data(const std::string& path) {
  return parse_pcd_data(path, read_text_file(path));
}

PcdData parse_pcd_data(const std::string& path, const std::string& data) {
  static_assert(std::endian::native == std::endian::little,
                "PCD binary data is little-endian; big-endian hosts would need byte swaps");
  const Prescan h = prescan_header(path, data);
  PcdData out;
  out.width = static_cast<std::uint32_t>(h.width);
  out.height = static_cast<std::uint32_t>(h.height);
  out.points = h.points;
  out.ascii = h.data_type == "ascii";
  // Row layout with overflow-checked sums: COUNTs come from the file and may be anything
  // (1 + 2^64 - 1 wraps to 0 and once made the ascii reader write past its buffer).
  std::uint64_t offset = 0, first = 0;
  for (std::size_t i = 0; i < h.names.size(); ++i) {
    if (h.counts[i] == 0) {
      throw InputError(path, "PCD field " + text_detail::quote(h.names[i]) +
                                 ": COUNT 0 (every field holds at least one value)");
    }
    out.fields.push_back(PcdField{h.names[i], h.types[i], h.sizes[i], h.counts[i], offset, first});
    std::uint64_t width = 0;
    if (__builtin_mul_overflow(h.sizes[i], h.counts[i], &width) ||
        __builtin_add_overflow(offset, width, &offset) ||
        __builtin_add_overflow(first, h.counts[i], &first)) {
      throw InputError(path, "PCD field " + text_detail::quote(h.names[i]) + ": COUNT " +
                                 std::to_string(h.counts[i]) + " makes the row size overflow");
    }
  }
  out.point_step = offset;
  out.values_per_point = first;
  // Every value of a point takes at least a byte of the body, so with one point or more the
  // body size check below bounds the COUNTs. With POINTS 0 nothing does, and a table reader
  // still makes a column per value: a file cannot describe more values per point than it has
  // bytes.
  if (h.points == 0 && out.values_per_point > data.size()) {
    throw InputError(path, "PCD header: the COUNTs add up to " +
                               std::to_string(out.values_per_point) +
                               " values per point, more than the file's " +
                               std::to_string(data.size()) + " bytes could hold");
  }
  check_body_size(path, data, h, out.point_step, out.values_per_point);
  // A body that really holds more points than the limit (a truncated claim is reported above).
  const std::uint64_t max_points = resource_limits().max_points;
  if (h.points > max_points) throw too_many_points(path, max_points);
  if (h.points == 0 && !out.ascii) return out;
  if (out.ascii) {
    read_ascii_body(path, data, h, out);
  } else {
    read_binary_body(path, data, h, out);
  }
  return out;
}

void read_pcd(const std::string& path, PointCloud& cloud) {
  parse_pcd(path, read_text_file(path), cloud);
}

void parse_pcd(const std::string& path, const std::string& data, PointCloud& cloud) {
  const PcdData pcd = parse_pcd_data(path, data);
  std::array<const PcdField*, 3> axis{};
  for (int a = 0; a < 3; ++a) {
    const std::string name(1, static_cast<char>('x' + a));
    axis[a] = pcd.find(name);
    if (axis[a] == nullptr) throw InputError(path, "PCD file has no field '" + name + "'");
  }
  cloud.width = pcd.width;
  cloud.height = pcd.height;
  cloud.points.reserve(pcd.points);
  cloud.source_index.reserve(pcd.points);
  for (std::size_t i = 0; i < pcd.points; ++i) {
    add_point(cloud, pcd.value(i, *axis[0]), pcd.value(i, *axis[1]), pcd.value(i, *axis[2]));
  }
}

}  // namespace nurbsreg::io::detail
