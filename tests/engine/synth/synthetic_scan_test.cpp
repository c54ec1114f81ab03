#include <gtest/gtest.h>

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

TEST(SyntheticScan, OptionsAreValidated) {
  SyntheticScanOptions options;
  options.outlier_fraction = 2.0;
  ASSERT_TRUE(options.validate());
  EXPECT_NE(options.validate()->find("outliers"), std::string::npos);
  options = {};
  options.points = 0;
  EXPECT_TRUE(options.validate());
}

}  // namespace
}  // namespace nurbsreg::engine
