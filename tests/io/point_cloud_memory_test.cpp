// Clouds from memory (a service's request body) decode exactly as the same bytes in a file.
#include "nurbsreg/io/point_cloud_memory.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/point_cloud.hpp"

namespace nurbsreg::io {
namespace {

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void expect_same(const PointCloud& a, const PointCloud& b) {
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.source_index, b.source_index);
  EXPECT_EQ(a.skipped_nonfinite, b.skipped_nonfinite);
  EXPECT_EQ(a.total, b.total);
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
}

TEST(PointCloudMemory, SameCloudAsTheFileReaders) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("nurbsreg-memory-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::vector<engine::Vec3> points;
  for (int i = 0; i < 500; ++i)
    points.emplace_back(0.1 * i, std::sin(0.3 * i), 1e3 - i);
  for (const PcdEncoding encoding :
       {PcdEncoding::ascii, PcdEncoding::binary, PcdEncoding::binary_compressed}) {
    const std::string path = (dir / "c.pcd").string();
    write_point_cloud(path, points, {encoding, false});
    const std::string bytes = file_bytes(path);
    EXPECT_EQ(sniff_cloud_encoding(bytes), CloudEncoding::pcd);
    expect_same(parse_point_cloud(bytes, CloudEncoding::pcd, "body"), read_point_cloud(path));
  }
  const std::string ply = (dir / "c.ply").string();
  write_point_cloud(ply, points);
  const std::string ply_bytes = file_bytes(ply);
  EXPECT_EQ(sniff_cloud_encoding(ply_bytes), CloudEncoding::ply);
  expect_same(parse_point_cloud(ply_bytes, CloudEncoding::ply, "body"), read_point_cloud(ply));
  std::filesystem::remove_all(dir);
}

TEST(PointCloudMemory, RawFloat32AndErrorsNamingTheLabel) {
  static_assert(std::endian::native == std::endian::little);
  const float xyz[] = {1.f,   2.f, 3.f,  std::numeric_limits<float>::quiet_NaN(), 0.f, 0.f,
                       -4.5f, 5.f, 6.25f};
  std::string raw(sizeof xyz, '\0');
  std::memcpy(raw.data(), xyz, sizeof xyz);
  const PointCloud cloud = parse_point_cloud(raw, CloudEncoding::float32_xyz, "body");
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.points[1], engine::Vec3(-4.5, 5.0, 6.25));
  EXPECT_EQ(cloud.source_index[1], 2u);
  EXPECT_EQ(cloud.skipped_nonfinite, 1u);
  try {
    parse_point_cloud(raw.substr(0, 13), CloudEncoding::float32_xyz, "request body");
    FAIL() << "13 bytes are not whole points";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("request body: ", 0), 0u) << e.what();
  }
  const std::string truncated =
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 10\n"
      "HEIGHT 1\nPOINTS 10\nDATA binary\n0123";
  EXPECT_THROW(parse_point_cloud(truncated, CloudEncoding::pcd, "request body"), InputError);
  EXPECT_THROW(parse_point_cloud("ply\nformat nonsense\n", CloudEncoding::ply, "b"), InputError);
}

}  // namespace
}  // namespace nurbsreg::io
