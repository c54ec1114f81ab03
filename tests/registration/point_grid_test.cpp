// The registration's grids order their cells by a radix sort (point_grid.cpp, cell_order): the
// same order as sorting (cell key, index) pairs, on which the noise estimate's sums, the scan's
// voxelised features and the model's keypoints depend to the bit. Checked here against that
// comparison sort, on clouds whose cells hold many points each (ties) and whose boxes need more
// than one radix digit.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "../../registration/src/grid_cell.hpp"
#include "../../registration/src/point_grid.hpp"

namespace nurbsreg::registration::detail {
namespace {

using engine::Vec3;

// A cloud of `n` points on a box of the given sides, a few per cell and some on a coarse lattice
// (exact duplicates, so cells tie on their first points too).
std::vector<Vec3> cloud(std::size_t n, const Vec3& sides, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> points(n);
  for (std::size_t i = 0; i < n; ++i) {
    Vec3 p(unit(rng) * sides.x(), unit(rng) * sides.y(), unit(rng) * sides.z());
    if (i % 5 == 0) p = (p / 0.5).array().floor().matrix() * 0.5;
    points[i] = p + Vec3(-3.0, 7.0, 1.0);
  }
  return points;
}

std::array<std::int64_t, 3> cell_of(const Vec3& p, const Vec3& origin, double cell) {
  const Vec3 s = (p - origin) / cell;
  return {static_cast<std::int64_t>(std::floor(s.x())),
          static_cast<std::int64_t>(std::floor(s.y())),
          static_cast<std::int64_t>(std::floor(s.z()))};
}

Vec3 lower_corner(const std::vector<Vec3>& points) {
  Vec3 lo = points.front();
  for (const Vec3& p : points)
    lo = lo.cwiseMin(p);
  return lo;
}

// voxelise by the comparison sort of (key, index) pairs: counts and nearest points per voxel.
std::pair<std::vector<std::uint32_t>, std::vector<std::uint32_t>> reference_voxels(
    const std::vector<Vec3>& points, double voxel) {
  const Vec3 origin = lower_corner(points);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto c = cell_of(points[i], origin, voxel);
    const auto m = [](std::int64_t x) {
      return static_cast<std::uint64_t>(x) & ((std::uint64_t{1} << 21) - 1);
    };
    keyed[i] = {(m(c[0]) << 42) | (m(c[1]) << 21) | m(c[2]), static_cast<std::uint32_t>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<std::uint32_t> counts, nearest;
  for (std::size_t k = 0; k < keyed.size();) {
    std::size_t e = k + 1;
    while (e < keyed.size() && keyed[e].first == keyed[k].first)
      ++e;
    Vec3 sum = Vec3::Zero();
    for (std::size_t j = k; j < e; ++j)
      sum += points[keyed[j].second];
    const Vec3 c = sum / static_cast<double>(e - k);
    std::uint32_t best = keyed[k].second;
    double best_d2 = std::numeric_limits<double>::infinity();
    for (std::size_t j = k; j < e; ++j) {
      const double d2 = (points[keyed[j].second] - c).squaredNorm();
      if (d2 < best_d2) {
        best_d2 = d2;
        best = keyed[j].second;
      }
    }
    counts.push_back(static_cast<std::uint32_t>(e - k));
    nearest.push_back(best);
    k = e;
  }
  return {counts, nearest};
}

TEST(PointGridOrder, VoxelsComeInKeyOrderWithTheComparisonSortsRepresentatives) {
  // 20,000 cells and more in the box: two radix digits of 11 bits.
  for (const double voxel : {0.05, 0.3, 2.0}) {
    const std::vector<Vec3> points = cloud(30000, Vec3(10.0, 6.0, 4.0), 3);
    const Voxelised v = voxelise(points, voxel);
    const auto [counts, nearest] = reference_voxels(points, voxel);
    EXPECT_EQ(v.counts, counts) << voxel;
    EXPECT_EQ(v.nearest, nearest) << voxel;
    EXPECT_EQ(voxel_counts(points, voxel), counts) << voxel;
  }
}

// Half the voxel count of a typical point: a median over points, which clutter's many sparse
// voxels do not decide. 100 surface voxels of 10 points and 400 clutter voxels of 1 or 2.
TEST(PointGridOrder, TheSurfacesVoxelCountIsATypicalPointsNotATypicalVoxels) {
  std::vector<std::uint32_t> counts;
  for (int i = 0; i < 100; ++i)
    counts.push_back(10);
  for (int i = 0; i < 400; ++i)
    counts.push_back(1 + static_cast<std::uint32_t>(i % 2));
  EXPECT_EQ(surface_voxel_count(counts, 1), 5u);
  EXPECT_EQ(surface_voxel_count(counts, 7), 7u);
  // A sparse scan: everything kept.
  EXPECT_EQ(surface_voxel_count(std::vector<std::uint32_t>(50, 1), 1), 1u);
}

TEST(PointGridOrder, NeighboursComeCellByCellInIndexOrder) {
  const double cell = 0.25;
  const std::vector<Vec3> points = cloud(20000, Vec3(8.0, 5.0, 3.0), 5);
  const PointGrid grid(points, cell);
  const Vec3 origin = lower_corner(points);
  std::vector<std::array<std::int64_t, 3>> cells(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    cells[i] = cell_of(points[i], origin, cell);
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
  for (int probe = 0; probe < 300; ++probe) {
    const Vec3 q = points[pick(rng)] + Vec3(0.01, -0.02, 0.005);
    std::vector<std::uint32_t> got;
    grid.for_each_within(q, cell, [&](std::uint32_t i, double) { got.push_back(i); });
    // The 27 cells around q's in (dx, dy, dz) order, each cell's points in index order.
    std::array<std::vector<std::uint32_t>, 27> by_cell;
    const auto c = cell_of(q, origin, cell);
    for (std::uint32_t i = 0; i < points.size(); ++i) {
      const auto& pc = cells[i];
      const std::int64_t dx = pc[0] - c[0], dy = pc[1] - c[1], dz = pc[2] - c[2];
      if (std::abs(dx) > 1 || std::abs(dy) > 1 || std::abs(dz) > 1) continue;
      if ((points[i] - q).squaredNorm() > cell * cell) continue;
      by_cell[static_cast<std::size_t>((dx + 1) * 9 + (dy + 1) * 3 + (dz + 1))].push_back(i);
    }
    std::vector<std::uint32_t> expected;
    for (const auto& in_cell : by_cell)
      expected.insert(expected.end(), in_cell.begin(), in_cell.end());
    EXPECT_GT(expected.size(), 0u);
    ASSERT_EQ(got, expected) << probe;
  }
}

// A cell coordinate beyond what a 64-bit integer holds (a tiny cell from a corrupt cache entry's
// voxel, or a finite scan point far from the rest) is clamped, not converted (undefined: the
// sanitizer build stops on it), and every neighbour within the radius is still found.
TEST(PointGridOrder, FarPointsAndTinyCellsStillFindEveryNeighbour) {
  EXPECT_EQ(cell_index(2.5), 2);
  EXPECT_EQ(cell_index(-0.5), -1);
  EXPECT_EQ(cell_index(1e30), std::int64_t{1} << 53);
  EXPECT_EQ(cell_index(-1e300), -(std::int64_t{1} << 53));
  EXPECT_EQ(cell_index(std::numeric_limits<double>::infinity()), std::int64_t{1} << 53);
  EXPECT_EQ(cell_index(std::numeric_limits<double>::quiet_NaN()), -(std::int64_t{1} << 53));
  std::vector<Vec3> points = cloud(200, Vec3(4.0, 3.0, 2.0), 7);
  points.push_back(Vec3(1e30, -2e25, 5.0));
  points.push_back(Vec3(1e30, -2e25, 5.5));
  for (const double cell : {1.0, 1e-200}) {
    const PointGrid grid(points, cell);
    for (std::size_t q = 0; q < points.size(); ++q) {
      std::vector<std::uint32_t> got, expected;
      grid.for_each_within(points[q], cell, [&](std::uint32_t i, double) { got.push_back(i); });
      for (std::uint32_t i = 0; i < points.size(); ++i) {
        if ((points[i] - points[q]).squaredNorm() <= cell * cell) expected.push_back(i);
      }
      std::sort(got.begin(), got.end());
      ASSERT_EQ(got, expected) << "cell " << cell << ", point " << q;
    }
    EXPECT_FALSE(voxelise(points, cell).counts.empty());
  }
}

}  // namespace
}  // namespace nurbsreg::registration::detail
