// Extension dispatch and the XYZ/TXT/CSV text reader.
//
// The text reader works on the whole file in memory and parses numbers with std::from_chars
// (locale-free, no allocation per token), which keeps it in the tens of millions of numbers per
// second: iostream extraction is several times slower on million-point scans.
#include <algorithm>
#include <array>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "nurbsreg/io/input_ranges.hpp"
#include "nurbsreg/io/resource_limits.hpp"
#include "point_cloud_detail.hpp"

namespace nurbsreg::io {
namespace detail {

namespace {

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

// Splits one line (comment already removed) into fields: whitespace runs separate fields, and
// so does a single comma with optional whitespace around it, so "1, 2 ,3" and "1 2 3" both give
// three fields while "1,,3" gives an empty middle field.
class FieldCursor {
 public:
  explicit FieldCursor(std::string_view line) : p_(line.data()), end_(line.data() + line.size()) {}

  // Next field, or false at the end of the line.
  bool next(std::string_view& field) {
    while (p_ != end_ && is_space(*p_))
      ++p_;
    if (!first_) {
      if (p_ != end_ && *p_ == ',') {
        ++p_;
        while (p_ != end_ && is_space(*p_))
          ++p_;
      }
    } else if (p_ != end_ && *p_ == ',') {
      // A line starting with a comma has an empty first field.
      first_ = false;
      field = std::string_view(p_, 0);
      return true;
    }
    first_ = false;
    if (p_ == end_) return false;
    const char* start = p_;
    while (p_ != end_ && !is_space(*p_) && *p_ != ',')
      ++p_;
    field = std::string_view(start, static_cast<std::size_t>(p_ - start));
    return true;
  }

 private:
  const char* p_;
  const char* end_;
  bool first_ = true;
};

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out)
    c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

}  // namespace

InputError too_many_points(const std::string& path, std::uint64_t limit) {
  return InputError(path, "more than " + std::to_string(limit) +
                              " points, the limit (raise it with NURBSREG_MAX_POINTS=<n>)");
}

void check_coordinate_range(const std::string& path, const PointCloud& cloud) {
  // One pass without branches in the common case: the largest magnitude first, the offending
  // point only when there is one.
  double largest = 0;
  for (const engine::Vec3& p : cloud.points)
    largest = std::max(largest, p.cwiseAbs().maxCoeff());
  if (largest <= kMaxCoordinate) return;
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    const engine::Vec3& p = cloud.points[i];
    for (int axis = 0; axis < 3; ++axis) {
      if (std::abs(p[axis]) > kMaxCoordinate) {
        throw InputError(path, "point " + std::to_string(cloud.source_index[i]) + ": " +
                                   static_cast<char>('x' + axis) + " = " +
                                   text_detail::format_number(p[axis]) +
                                   " is beyond the supported range |coordinate| <= 1e15 " +
                                   "(README \"Coordinate range\")");
      }
    }
  }
}

void read_text(const std::string& path, PointCloud& cloud) {
  const std::string data = read_text_file(path);
  const std::uint64_t max_points = resource_limits().max_points;
  const std::uint64_t lines =
      static_cast<std::uint64_t>(std::count(data.begin(), data.end(), '\n')) + 1;
  cloud.points.reserve(std::min(lines, max_points));
  cloud.source_index.reserve(cloud.points.capacity());

  // Columns holding x, y, z: 0, 1, 2 unless a header line names them.
  std::array<std::size_t, 3> column{0, 1, 2};
  std::size_t needed = 3;  // fields a data line must have
  bool seen_content = false;

  const char* p = data.data();
  const char* const end = p + data.size();
  if (data.starts_with(kUtf8Bom)) p += kUtf8Bom.size();  // spreadsheet exports start with one
  std::size_t line_number = 0;
  while (p < end) {
    ++line_number;
    const char* eol =
        static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)));
    if (eol == nullptr) eol = end;
    std::string_view line(p, static_cast<std::size_t>(eol - p));
    p = eol + 1;
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) {
      line = line.substr(0, hash);
    }
    FieldCursor cursor(line);
    std::string_view field;
    if (!cursor.next(field)) continue;  // blank or comment-only line
    const auto at_line = [&](const std::string& what) {
      return InputError(path, "line " + std::to_string(line_number) + ": " + what);
    };

    double value = 0.0;
    if (!seen_content) {
      seen_content = true;
      if (!field.empty() && !parse_number(field, value) && !text_detail::out_of_range(field)) {
        // A header naming the columns (`x,y,z` or `index,x,y,z,foot_x,...`).
        std::array<bool, 3> found{false, false, false};
        std::size_t index = 0;
        do {
          const std::string name = lower(field);
          for (int axis = 0; axis < 3; ++axis) {
            if (!found[axis] && name == std::string(1, static_cast<char>('x' + axis))) {
              column[axis] = index;
              found[axis] = true;
            }
          }
          ++index;
        } while (cursor.next(field));
        if (!found[0] || !found[1] || !found[2]) {
          throw at_line("expected 3 numbers (x y z) or a header naming columns x, y, z");
        }
        needed = std::max({column[0], column[1], column[2]}) + 1;
        continue;
      }
    }

    std::array<double, 3> xyz{};
    std::size_t index = 0;
    std::size_t got = 0;
    do {
      for (int axis = 0; axis < 3; ++axis) {
        if (column[axis] != index) continue;
        if (!parse_number(field, xyz[axis])) {
          throw at_line("column " + std::to_string(index + 1) + ": " +
                        text_detail::bad_number(field));
        }
        ++got;
      }
      ++index;
    } while (index < needed && cursor.next(field));
    if (got < 3) {
      throw at_line(needed == 3 ? "expected 3 numbers (x y z), got " + std::to_string(index)
                                : "expected " + std::to_string(needed) +
                                      " columns as in the header, got " + std::to_string(index));
    }
    if (cloud.total == max_points) throw too_many_points(path, max_points);
    add_point(cloud, xyz[0], xyz[1], xyz[2]);
  }
}

}  // namespace detail

PointCloud read_point_cloud(const std::string& path) {
  PointCloud cloud;
  const std::string ext = detail::lower_extension(path);
  if (ext == ".pcd") {
    detail::read_pcd(path, cloud);
  } else if (ext == ".ply") {
    detail::read_ply(path, cloud);
  } else if (ext == ".xyz" || ext == ".txt" || ext == ".csv") {
    detail::read_text(path, cloud);
  } else {
    throw InputError(path, (ext.empty() ? std::string("file name has no extension")
                                        : "unsupported point-cloud format " + detail::quote(ext)) +
                               " (supported: .pcd, .ply, .xyz, .txt, .csv)");
  }
  if (cloud.height == 0) {
    cloud.width = static_cast<std::uint32_t>(cloud.total);
    cloud.height = 1;
  }
  return cloud;
}

PointCloud read_scan(const std::string& path) {
  PointCloud cloud = read_point_cloud(path);
  detail::check_coordinate_range(path, cloud);
  if (cloud.size() == 0) {
    throw InputError(path, cloud.total == 0
                               ? std::string("the scan has no points")
                               : "the scan has no finite points (all " +
                                     std::to_string(cloud.total) + " are NaN or infinite)");
  }
  return cloud;
}

}  // namespace nurbsreg::io
