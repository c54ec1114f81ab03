#pragma once
// Helpers shared by the point-cloud and point-table readers and writers (private to io).

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/point_cloud.hpp"

namespace nurbsreg::io::detail {

// The whole file as bytes. Throws InputError when it cannot be opened or read.
std::string read_file(const std::string& path);

// Byte-order mark that some editors and spreadsheets put at the start of text files.
inline constexpr std::string_view kUtf8Bom = "\xEF\xBB\xBF";

// Lower-case extension including the dot (".pcd"), empty when there is none.
std::string lower_extension(const std::string& path);

// Readers of the individual formats; they fill `cloud` (initially empty) and throw InputError.
void read_pcd(const std::string& path, PointCloud& cloud);
void read_ply(const std::string& path, PointCloud& cloud);
void read_text(const std::string& path, PointCloud& cloud);
// The same for bytes already in memory (a service's request body); `path` only labels errors.
void parse_pcd(const std::string& path, const std::string& data, PointCloud& cloud);
void parse_ply(const std::string& path, const std::string& data, PointCloud& cloud);

// A PCD file's fields and values, as read by read_pcd_data (header checked, body complete).
struct PcdField {
  std::string name;
  char type = 'F';         // F, I or U
  std::size_t size = 4;    // bytes: 1, 2, 4 or 8
  std::size_t count = 1;   // values per point
  std::size_t offset = 0;  // byte offset in a binary row (binary encodings)
  std::size_t first = 0;   // index of its first value among a row's values (ascii)
};

struct PcdData {
  std::vector<PcdField> fields;
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::size_t points = 0;
  bool ascii = false;
  std::size_t point_step = 0;        // binary: bytes per row
  std::vector<std::uint8_t> rows;    // binary: row-major, points x point_step
  std::size_t values_per_point = 0;  // ascii: sum of counts
  std::vector<double> values;        // ascii: row-major, points x values_per_point

  // Value k of field f of point i, converted to double.
  double value(std::size_t i, const PcdField& f, std::size_t k = 0) const;
  // nullptr when absent.
  const PcdField* find(std::string_view name) const;
};

PcdData read_pcd_data(const std::string& path);
PcdData parse_pcd_data(const std::string& path, const std::string& data);

// A token from the file for an error message: quoted, at most 40 characters, control and
// non-ASCII bytes shown as '?' so that the message stays one printable line.
inline std::string quote(std::string_view token) {
  constexpr std::size_t kMax = 40;
  std::string out = "'";
  for (const char c : token.substr(0, kMax)) {
    out.push_back(c >= 0x20 && c < 0x7f ? c : '?');
  }
  if (token.size() > kMax) out += "...";
  return out + "'";
}

// Appends point `index` of the file, or counts it as skipped when a coordinate is not finite.
inline void add_point(PointCloud& cloud, double x, double y, double z) {
  const std::uint64_t index = cloud.total++;
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
    ++cloud.skipped_nonfinite;
    return;
  }
  cloud.points.emplace_back(x, y, z);
  cloud.source_index.push_back(index);
}

// Parses a whole token as a double. Accepts what std::from_chars accepts (including `nan`,
// `inf`, `infinity` in any case) plus a leading '+'. Returns false unless the entire token is a
// number.
inline bool parse_double(std::string_view token, double& value) {
  const char* first = token.data();
  const char* last = first + token.size();
  if (first != last && *first == '+') ++first;
  if (first == last) return false;
  const auto [end, ec] = std::from_chars(first, last, value);
  // Out-of-range magnitudes (1e999) become inf/0 like strtod would; anything else is an error.
  if (ec == std::errc::result_out_of_range) {
    value = std::strtod(std::string(token).c_str(), nullptr);
    return end == last;
  }
  return ec == std::errc() && end == last;
}

// Shortest representation that reads back to the identical value (std::to_chars without a
// format, C++17 [charconv]); integers print exactly.
template <class T>
inline void append_number(std::string& out, T value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  out.append(buffer, result.ptr);
}

}  // namespace nurbsreg::io::detail
