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
#include "text_io.hpp"

namespace nurbsreg::io::detail {

using text_detail::kUtf8Bom;
using text_detail::lower_extension;
using text_detail::parse_number;
using text_detail::quote;
using text_detail::read_text_file;

// The error for a cloud of more than `limit` points (resource_limits.hpp).
InputError too_many_points(const std::string& path, std::uint64_t limit);
// Throws InputError naming the first point with a coordinate beyond kMaxCoordinate
// (input_ranges.hpp).
void check_coordinate_range(const std::string& path, const PointCloud& cloud);

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

using text_detail::append_number;

}  // namespace nurbsreg::io::detail
