// The coarse stage's descriptors (features.cpp, describe): four angles per pair of neighbours,
// soft-binned on a square-root scale, each block normalised to 100, then FPFH's own histogram
// plus the mean of the neighbours'. The implementation gathers the pairs' cosines in float and
// turns them into angles by a polynomial in one vectorised pass; checked here against a plain
// double-precision reference written from the definition (the library's asin and acos, each
// pair binned as it comes, neighbours by a scan over all points), on points of a curved surface
// with its exact normals and on a random cloud with random normals (every angle, both signs).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "../../registration/src/features.hpp"
#include "../../registration/src/point_grid.hpp"

namespace nurbsreg::registration::detail {
namespace {

using engine::Vec3;

// Adds `fraction` (an angle as a fraction of a right angle) to block `block` of h, as the
// definition says: position sqrt(fraction) * bins - 0.5, its weight shared linearly between the
// two nearest bin centres, all of it to an end bin beyond the first or last centre.
void bin(std::array<double, kDescriptorSize>& h, int block, double fraction) {
  const double x = std::sqrt(std::clamp(fraction, 0.0, 1.0)) * kBinsPerFeature - 0.5;
  const double lower = std::floor(x);
  const double t = x - lower;
  const int lo = static_cast<int>(lower);
  const auto at = [&](int b) -> double& {
    return h[static_cast<std::size_t>(block * kBinsPerFeature +
                                      std::clamp(b, 0, kBinsPerFeature - 1))];
  };
  at(lo) += 1.0 - t;
  at(lo + 1) += t;
}

DescriptorMatrix reference_descriptors(const std::vector<Vec3>& points,
                                       const std::vector<Vec3>& normals, double radius) {
  const std::size_t n = points.size();
  const double half_pi = 0.5 * std::numbers::pi;
  std::vector<std::array<double, kDescriptorSize>> spfh(n);
  std::vector<int> count(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    std::array<double, kDescriptorSize> h{};
    for (std::size_t j = 0; j < n; ++j) {
      const Vec3 e = points[j] - points[i];
      const double d2 = e.squaredNorm();
      if (j == i || !(d2 > 0.0) || d2 > radius * radius) continue;
      const Vec3 d = e / std::sqrt(d2);
      const Vec3& ni = normals[i];
      const Vec3& nj = normals[j];
      const Vec3 v = ni.cross(d);
      const double alpha = v.norm() > 1e-12 ? std::abs(v.dot(nj)) / v.norm() : 0.0;
      bin(h, 0, std::asin(std::min(1.0, std::abs(ni.dot(d)))) / half_pi);
      bin(h, 1, std::asin(std::min(1.0, std::abs(nj.dot(d)))) / half_pi);
      bin(h, 2, std::acos(std::min(1.0, std::abs(ni.dot(nj)))) / half_pi);
      bin(h, 3, std::asin(std::min(1.0, alpha)) / half_pi);
      ++count[i];
    }
    for (double& b : h)
      b *= count[i] > 0 ? 100.0 / count[i] : 0.0;
    spfh[i] = h;
  }
  DescriptorMatrix out(static_cast<Eigen::Index>(n), kDescriptorSize);
  for (std::size_t i = 0; i < n; ++i) {
    std::array<double, kDescriptorSize> sum{};
    int neighbours = 0;
    for (std::size_t j = 0; j < n; ++j) {
      if (j == i || count[j] == 0 || (points[j] - points[i]).squaredNorm() > radius * radius)
        continue;
      for (int k = 0; k < kDescriptorSize; ++k)
        sum[static_cast<std::size_t>(k)] += spfh[j][static_cast<std::size_t>(k)];
      ++neighbours;
    }
    for (int k = 0; k < kDescriptorSize; ++k) {
      const auto s = static_cast<std::size_t>(k);
      out(static_cast<Eigen::Index>(i), k) = static_cast<float>(
          neighbours > 0 ? 0.5 * spfh[i][s] + 0.5 * sum[s] / neighbours : spfh[i][s]);
    }
  }
  return out;
}

// The largest difference of any bin (descriptors are on a scale of 100 a block).
float largest_difference(const DescriptorMatrix& a, const DescriptorMatrix& b) {
  return (a - b).cwiseAbs().maxCoeff();
}

// Every pair's bin position is within 1e-3 of a bin of the definition's (the polynomial's worst,
// near an angle of 0) and the sums run in float: a bin moves by at most 0.1% of a pair's weight,
// 0.1 on a scale of 100 per block if every pair's error went the same way; the cases below
// differ by about 1e-3 at most.
constexpr float kTolerance = 0.005f;

TEST(Descriptors, CurvedSurfaceWithExactNormalsMatchesThePlainDefinition) {
  // A saddle z = x^2 - y^2 over [-1, 1]^2, its unit normals, random signs (a scan's
  // normals have none); neighbourhoods of about 40 points.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<Vec3> points, normals;
  for (int k = 0; k < 900; ++k) {
    const double x = unit(rng), y = unit(rng);
    points.emplace_back(x, y, x * x - y * y);
    const Vec3 n = Vec3(-2.0 * x, 2.0 * y, 1.0).normalized();
    normals.push_back(unit(rng) < 0.0 ? Vec3(-n) : n);
  }
  const double radius = 0.3;
  const PointGrid grid(points, radius);
  const DescriptorMatrix fast = describe(points, normals, grid, radius);
  const DescriptorMatrix plain = reference_descriptors(points, normals, radius);
  ASSERT_EQ(fast.rows(), plain.rows());
  EXPECT_LT(largest_difference(fast, plain), kTolerance);
  // Not trivially equal: the angles between the normals reach most bins of their block.
  int reached = 0;
  for (int k = 2 * kBinsPerFeature; k < 3 * kBinsPerFeature; ++k)
    reached += plain.col(k).maxCoeff() > 1.0f ? 1 : 0;
  EXPECT_GE(reached, 5);
}

TEST(Descriptors, RandomNormalsCoverEveryAngleAndMatchThePlainDefinition) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<Vec3> points, normals;
  for (int k = 0; k < 700; ++k) {
    points.emplace_back(unit(rng), unit(rng), 0.5 * unit(rng));
    Vec3 n(unit(rng), unit(rng), unit(rng));
    normals.push_back(n.norm() > 1e-3 ? n.normalized() : Vec3::UnitX());
  }
  // A duplicate point (a pair at distance 0 is no pair) and exactly parallel normals along the
  // line between two points (alpha's degenerate case).
  points.push_back(points[0]);
  normals.push_back(normals[0]);
  points.push_back(points[1] + 0.05 * normals[1]);
  normals.push_back(normals[1]);
  const double radius = 0.4;
  const PointGrid grid(points, radius);
  const DescriptorMatrix fast = describe(points, normals, grid, radius);
  const DescriptorMatrix plain = reference_descriptors(points, normals, radius);
  EXPECT_LT(largest_difference(fast, plain), kTolerance);
  // Every bin of every block is reached somewhere.
  for (int k = 0; k < kDescriptorSize; ++k)
    EXPECT_GT(plain.col(k).maxCoeff(), 0.5f) << "bin " << k;
}

}  // namespace
}  // namespace nurbsreg::registration::detail
