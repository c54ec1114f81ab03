// write_point_cloud: PCD through write_pcd, PLY (binary_little_endian) and text written here.
#include <bit>
#include <cstring>
#include <ostream>

#include "nurbsreg/io/atomic_file.hpp"
#include "point_cloud_detail.hpp"

namespace nurbsreg::io {
namespace {

template <class T>
void write_pcd_points(const std::string& path, std::span<const engine::Vec3> points,
                      PcdEncoding encoding) {
  PointTable table;
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<T>& values = table.add_column<T>(std::string(1, static_cast<char>('x' + axis)));
    values.resize(points.size());
    for (std::size_t i = 0; i < points.size(); ++i)
      values[i] = static_cast<T>(points[i][axis]);
  }
  write_pcd(path, table, encoding);
}

template <class T>
void write_ply_points(const std::string& path, std::span<const engine::Vec3> points) {
  static_assert(std::endian::native == std::endian::little, "writes binary_little_endian");
  const char* type = sizeof(T) == 8 ? "double" : "float";
  const std::string header = std::string("ply\nformat binary_little_endian 1.0\n") +
                             "comment written by nurbsreg\nelement vertex " +
                             std::to_string(points.size()) + "\nproperty " + type +
                             " x\nproperty " + type + " y\nproperty " + type + " z\nend_header\n";
  write_atomically(path, [&](std::ostream& out) {
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    constexpr std::size_t kChunk = 1 << 16;
    std::vector<T> buffer(3 * kChunk);
    for (std::size_t first = 0; first < points.size(); first += kChunk) {
      const std::size_t count = std::min(kChunk, points.size() - first);
      for (std::size_t i = 0; i < count; ++i) {
        for (int axis = 0; axis < 3; ++axis) {
          buffer[3 * i + axis] = static_cast<T>(points[first + i][axis]);
        }
      }
      out.write(reinterpret_cast<const char*>(buffer.data()),
                static_cast<std::streamsize>(count * 3 * sizeof(T)));
    }
  });
}

void write_text_points(const std::string& path, std::span<const engine::Vec3> points,
                       bool double_precision, char separator, bool header) {
  write_atomically(path, [&](std::ostream& out) {
    std::string buffer;
    constexpr std::size_t kFlush = 1 << 20;
    buffer.reserve(kFlush + 256);
    if (header) buffer += "x,y,z\n";
    for (const engine::Vec3& p : points) {
      for (int axis = 0; axis < 3; ++axis) {
        if (axis != 0) buffer.push_back(separator);
        if (double_precision) {
          detail::append_number(buffer, p[axis]);
        } else {
          detail::append_number(buffer, static_cast<float>(p[axis]));
        }
      }
      buffer.push_back('\n');
      if (buffer.size() >= kFlush) {
        out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
        buffer.clear();
      }
    }
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  });
}

}  // namespace

void write_point_cloud(const std::string& path, std::span<const engine::Vec3> points,
                       const PointCloudWriteOptions& options) {
  const std::string ext = detail::lower_extension(path);
  if (ext == ".pcd") {
    if (options.double_precision) {
      write_pcd_points<double>(path, points, options.pcd_encoding);
    } else {
      write_pcd_points<float>(path, points, options.pcd_encoding);
    }
  } else if (ext == ".ply") {
    if (options.double_precision) {
      write_ply_points<double>(path, points);
    } else {
      write_ply_points<float>(path, points);
    }
  } else if (ext == ".xyz" || ext == ".txt") {
    write_text_points(path, points, options.double_precision, ' ', false);
  } else if (ext == ".csv") {
    write_text_points(path, points, options.double_precision, ',', true);
  } else {
    throw OutputError(path, "unsupported point-cloud format '" + ext +
                                "' (supported: .pcd, .ply, .xyz, .txt, .csv)");
  }
}

}  // namespace nurbsreg::io
