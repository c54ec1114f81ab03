// The viewer's subset, the PLY file (read back with the project's reader and field by field) and
// the all-or-nothing output folder.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>

#include "nurbsreg/inspect/deviation_ply.hpp"
#include "nurbsreg/inspect/output_folder.hpp"
#include "nurbsreg/inspect/viewer_subset.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "support/run_command.hpp"

namespace nurbsreg::inspect {
namespace {

using engine::Vec3;

TEST(ViewerSubset, SmallScanKeepsEveryPoint) {
  const std::vector<Vec3> points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const ViewerSubset s = viewer_subset(points, 10);
  EXPECT_EQ(s.indices, (std::vector<std::uint32_t>{0, 1, 2}));
  EXPECT_EQ(s.cell, 0.0);
}

TEST(ViewerSubset, LargeScanIsThinnedEvenly) {
  // A plane sampled densely on its left half and sparsely on its right half.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> points;
  for (int i = 0; i < 80000; ++i)
    points.emplace_back(unit(rng) * 50, unit(rng) * 100, 0);
  for (int i = 0; i < 20000; ++i)
    points.emplace_back(50 + unit(rng) * 50, unit(rng) * 100, 0);
  const ViewerSubset s = viewer_subset(points, 5000);
  EXPECT_LE(s.indices.size(), 5000u);
  EXPECT_GE(s.indices.size(), 4000u);
  EXPECT_TRUE(std::is_sorted(s.indices.begin(), s.indices.end()));
  std::size_t left = 0;
  for (const std::uint32_t i : s.indices)
    left += points[i].x() < 50;
  // Even in space: the halves get about the same share although their densities differ 4:1.
  const double share = double(left) / double(s.indices.size());
  EXPECT_GT(share, 0.4);
  EXPECT_LT(share, 0.6);
}

PointDeviations sample_deviations() {
  PointDeviations dev;
  const double d[] = {-0.5, -0.05, 0.0, 0.02, 0.2, 1.5};
  for (int i = 0; i < 6; ++i) {
    dev.points.emplace_back(i * 1.5, -i * 0.25, 3.0 + i);
    dev.signed_distance.push_back(d[i]);
    dev.face.push_back(i % 2);
    dev.u.push_back(0.125 * i);
    dev.v.push_back(1.0 - 0.125 * i);
    dev.source_index.push_back(2 * i + 1);
  }
  return dev;
}

TEST(DeviationPly, ReadsBackWithTheProjectsReaderAndFieldByField) {
  test::ScratchDir dir("inspect-ply");
  const PointDeviations dev = sample_deviations();
  const ColourScale scale = ColourScale::around(Tolerance{-0.1, 0.1}, ColourScheme::metrology);
  const std::string path = dir / "d.ply";
  write_deviation_ply(path, dev, scale);

  const io::PointCloud cloud = io::read_point_cloud(path);
  ASSERT_EQ(cloud.size(), dev.size());
  for (std::size_t i = 0; i < dev.size(); ++i) {
    EXPECT_EQ(cloud.points[i], dev.points[i].cast<float>().cast<double>());
  }

  const std::string bytes = test::read_text(path);
  const std::string end = "end_header\n";
  const std::size_t body = bytes.find(end) + end.size();
  const std::string header = bytes.substr(0, body);
  EXPECT_NE(header.find("format binary_little_endian 1.0"), std::string::npos);
  EXPECT_NE(header.find("element vertex 6\n"), std::string::npos);
  EXPECT_NE(header.find("property float signed_distance\nproperty int face\n"), std::string::npos);
  constexpr std::size_t record = 12 + 3 + 4 + 4 + 16 + 4 + 4 + 4 + 4;
  ASSERT_EQ(bytes.size(), body + record * dev.size());
  for (std::size_t i = 0; i < dev.size(); ++i) {
    const char* r = bytes.data() + body + i * record;
    const Rgb c{static_cast<std::uint8_t>(r[12]), static_cast<std::uint8_t>(r[13]),
                static_cast<std::uint8_t>(r[14])};
    EXPECT_EQ(c, scale.colour(dev.signed_distance[i]));
    float d;
    std::int32_t face;
    double u, v;
    std::int32_t side;
    std::int32_t index;
    std::memcpy(&d, r + 15, 4);
    std::memcpy(&face, r + 19, 4);
    std::memcpy(&u, r + 23, 8);
    std::memcpy(&v, r + 31, 8);
    std::memcpy(&side, r + 39, 4);
    std::memcpy(&index, r + 43, 4);
    EXPECT_EQ(d, static_cast<float>(dev.signed_distance[i]));
    EXPECT_EQ(face, dev.face[i]);
    EXPECT_EQ(u, dev.u[i]);
    EXPECT_EQ(v, dev.v[i]);
    EXPECT_EQ(side, dev.signed_distance[i] < -0.1 ? -1 : dev.signed_distance[i] > 0.1 ? 1 : 0);
    EXPECT_EQ(static_cast<std::uint64_t>(index), dev.source_index[i]);
  }
}

TEST(OutputFolder, NothingAppearsUntilCommitAndNothingStaysOnFailure) {
  test::ScratchDir dir("inspect-folder");
  const std::filesystem::path out = dir.path() / "report";
  {
    OutputFolder folder(out);
    std::ofstream(folder.path("a.txt")) << "a";
    EXPECT_FALSE(std::filesystem::exists(out));
    // No commit: a failed run.
  }
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
  {
    OutputFolder folder(out);
    std::ofstream(folder.path("a.txt")) << "a";
    folder.commit();
  }
  EXPECT_TRUE(std::filesystem::exists(out / "a.txt"));
  {
    // Into an existing folder: files replaced one by one, others kept.
    std::ofstream(out / "keep.txt") << "k";
    OutputFolder folder(out);
    std::ofstream(folder.path("a.txt")) << "b";
    folder.commit();
  }
  EXPECT_EQ(test::read_text(out / "a.txt"), "b");
  EXPECT_TRUE(std::filesystem::exists(out / "keep.txt"));
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir.path()))
    ++entries;
  EXPECT_EQ(entries, 1u);  // no staging folder left beside it
}

TEST(OutputFolder, UnusablePlacesFailUpFront) {
  test::ScratchDir dir("inspect-folder-bad");
  std::ofstream(dir / "file") << "x";
  EXPECT_THROW(OutputFolder(dir.path() / "file"), std::runtime_error);
  EXPECT_THROW(OutputFolder(dir.path() / "file" / "sub"), std::runtime_error);
  EXPECT_THROW(OutputFolder(dir.path() / "missing" / "sub"), std::runtime_error);
}

}  // namespace
}  // namespace nurbsreg::inspect
