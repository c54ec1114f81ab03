// Point clouds from memory: the file readers' parsers on a caller's bytes.
#include "nurbsreg/io/point_cloud_memory.hpp"

#include <bit>
#include <cstring>

#include "point_cloud_detail.hpp"

namespace nurbsreg::io {
namespace {

void parse_float32_xyz(const std::string& label, const std::string& bytes, PointCloud& cloud) {
  static_assert(std::endian::native == std::endian::little,
                "raw float32 bodies are little-endian; big-endian hosts would need byte swaps");
  constexpr std::size_t kStride = 3 * sizeof(float);
  if (bytes.size() % kStride != 0) {
    throw InputError(label, "raw float32 x y z data of " + std::to_string(bytes.size()) +
                                " bytes is not a whole number of 12-byte points");
  }
  const std::size_t n = bytes.size() / kStride;
  cloud.points.reserve(n);
  cloud.source_index.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    float xyz[3];
    std::memcpy(xyz, bytes.data() + i * kStride, kStride);
    detail::add_point(cloud, xyz[0], xyz[1], xyz[2]);
  }
}

}  // namespace

CloudEncoding sniff_cloud_encoding(std::string_view bytes) {
  if (bytes.starts_with("ply\n") || bytes.starts_with("ply\r\n")) return CloudEncoding::ply;
  return CloudEncoding::pcd;
}

PointCloud parse_point_cloud(const std::string& bytes, CloudEncoding encoding,
                             const std::string& label) {
  PointCloud cloud;
  switch (encoding) {
    case CloudEncoding::pcd:
      detail::parse_pcd(label, bytes, cloud);
      break;
    case CloudEncoding::ply:
      detail::parse_ply(label, bytes, cloud);
      break;
    case CloudEncoding::float32_xyz:
      parse_float32_xyz(label, bytes, cloud);
      break;
  }
  // As read_point_cloud does for files.
  if (cloud.height == 0) {
    cloud.width = static_cast<std::uint32_t>(cloud.total);
    cloud.height = 1;
  }
  return cloud;
}

}  // namespace nurbsreg::io
