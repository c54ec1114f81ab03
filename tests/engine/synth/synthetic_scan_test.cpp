#include <gtest/gtest.h>

#include <cmath>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"

namespace nurbsreg::engine {
namespace {

Model sphere_model() {
  Model m;
  m.surfaces.push_back(make_sphere(Vec3::Zero(), 10.0));
  return m;
}

TEST(SyntheticScan, PoseMapsScanBackOntoTheModel) {
  SyntheticScanOptions options;
  options.points = 2000;
  options.T_scan_model = pose_from_euler_degrees(5, -3, 10, Vec3(1, 2, 3));
  const SyntheticScan scan = make_synthetic_scan(sphere_model(), options);
  ASSERT_EQ(scan.points.size(), 2000u);
  for (const Vec3& p : scan.points)
    EXPECT_NEAR((scan.T_model_scan * p).norm(), 10.0, 1e-9);
}

TEST(SyntheticScan, NoiseOutliersAndPartialView) {
  SyntheticScanOptions options;
  options.points = 20000;
  options.noise_sigma = 0.01;
  options.outlier_fraction = 0.1;
  options.view_fraction = 0.3;
  options.view_direction = Vec3(0, 0, 1);
  const SyntheticScan scan = make_synthetic_scan(sphere_model(), options);
  ASSERT_EQ(scan.points.size(), 20000u);
  std::size_t outliers = 0;
  double sum_sq = 0.0;
  double min_z = 1e9;
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    if (!scan.on_model[i]) {
      ++outliers;
      continue;
    }
    const double r = scan.points[i].norm() - 10.0;
    sum_sq += r * r;
    min_z = std::min(min_z, scan.points[i].z());
  }
  EXPECT_EQ(outliers, 2000u);
  const double sigma = std::sqrt(sum_sq / (scan.points.size() - outliers));
  EXPECT_NEAR(sigma, 0.01, 0.0005);
  // The top 30% of a sphere's area is the cap above z = 10 * (1 - 2 * 0.3) = 4.
  EXPECT_NEAR(min_z, 4.0, 0.1);
}

// The clutter: uniform in the scan's box, i.e. the box of what the scanner sees (a
// partial view's own box, not the model's). The cap of a sphere seen from above is the box
// [-r_cap, r_cap]^2 x [4, 10]; every outlier lies in it and they fill it.
TEST(SyntheticScan, OutliersFillTheBoxOfTheVisiblePart) {
  SyntheticScanOptions options;
  options.points = 20000;
  options.outlier_fraction = 0.3;
  options.view_fraction = 0.3;
  const SyntheticScan scan = make_synthetic_scan(sphere_model(), options);
  Aabb seen, outliers;
  for (std::size_t i = 0; i < scan.points.size(); ++i)
    (scan.on_model[i] ? seen : outliers).extend(scan.points[i]);
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_GE(outliers.lo[axis], seen.lo[axis] - 0.05) << axis;
    EXPECT_LE(outliers.hi[axis], seen.hi[axis] + 0.05) << axis;
    EXPECT_GT(outliers.hi[axis] - outliers.lo[axis], 0.95 * (seen.hi[axis] - seen.lo[axis]))
        << axis;
  }
  EXPECT_NEAR(seen.lo.z(), 4.0, 0.1);
}

// A fixture under the part: on the plane through the visible part's lowest point along `up`,
// wider than the part by half its extent on every side, with the scan's noise along `up`.
TEST(SyntheticScan, AFixturePlaneUnderThePart) {
  SyntheticScanOptions options;
  options.points = 20000;
  options.noise_sigma = 0.01;
  options.outlier_fraction = 0.1;
  options.fixture_fraction = 0.25;
  options.fixture_up = Vec3(1, 0, 0);
  const SyntheticScan scan = make_synthetic_scan(sphere_model(), options);
  std::size_t off_model = 0, on_plane = 0;
  double sum_sq = 0.0;
  Aabb plane;
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    if (scan.on_model[i]) continue;
    ++off_model;
    const Vec3& p = scan.points[i];
    if (std::abs(p.x() + 10.0) < 0.1 && (std::abs(p.y()) > 10.5 || std::abs(p.z()) > 10.5)) {
      // Beyond the sphere's footprint: no outlier of the sphere's box can be there.
      ++on_plane;
    }
    if (std::abs(p.x() + 10.0) < 0.1 && std::abs(p.y()) <= 20.0 && std::abs(p.z()) <= 20.0) {
      sum_sq += (p.x() + 10.0) * (p.x() + 10.0);
      plane.extend(p);
    }
  }
  EXPECT_EQ(off_model, 7000u);
  // The plane's square [-20, 20]^2 holds 5,000 points, 3,000+ of them beyond [-10.5, 10.5]^2.
  EXPECT_GT(on_plane, 3000u);
  EXPECT_LT(plane.lo.y(), -19.5);
  EXPECT_GT(plane.hi.y(), 19.5);
  EXPECT_LT(plane.lo.z(), -19.5);
  EXPECT_GT(plane.hi.z(), 19.5);
  EXPECT_NEAR(std::sqrt(sum_sq / 5000.0), 0.01, 0.002);
}

TEST(SyntheticScan, OptionsAreValidated) {
  SyntheticScanOptions options;
  options.outlier_fraction = 2.0;
  ASSERT_TRUE(options.validate());
  EXPECT_NE(options.validate()->find("outliers"), std::string::npos);
  options = {};
  options.points = 0;
  EXPECT_TRUE(options.validate());
  options = {};
  options.outlier_fraction = 0.6;
  options.fixture_fraction = 0.5;
  ASSERT_TRUE(options.validate());
  EXPECT_NE(options.validate()->find("fixture"), std::string::npos);
  options.fixture_fraction = 0.4;
  options.fixture_up = Vec3::Zero();
  ASSERT_TRUE(options.validate());
  EXPECT_NE(options.validate()->find("up"), std::string::npos);
}

}  // namespace
}  // namespace nurbsreg::engine
