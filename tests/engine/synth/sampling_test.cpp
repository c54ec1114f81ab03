// Area-uniform sampling checked on exact shapes whose areas and normals are known.
#include <gtest/gtest.h>

#include <tbb/global_control.h>

#include <numbers>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/engine/trim_region.hpp"
#include "support/polygon_loop.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

TEST(Sampling, SphereAreaAndNormals) {
  Model model;
  model.surfaces.push_back(make_sphere(Vec3(1, 2, 3), 2.0));
  EXPECT_NEAR(surface_area(model), 4.0 * std::numbers::pi * 4.0, 1e-6 * 16.0 * std::numbers::pi);
  const auto samples = sample_surfaces(model, 20000, 1);
  ASSERT_EQ(samples.size(), 20000u);
  // Uniform on a sphere: z is uniform in [-r, r] (Archimedes); compare bin counts.
  int bins[4] = {0, 0, 0, 0};
  for (const SurfaceSample& s : samples) {
    const Vec3 radial = s.point - Vec3(1, 2, 3);
    EXPECT_NEAR(radial.norm(), 2.0, 1e-12);
    // Outward or inward, the normal is radial.
    EXPECT_NEAR(std::abs(s.normal.dot(radial.normalized())), 1.0, 1e-9);
    ++bins[std::clamp(static_cast<int>((radial.z() + 2.0) / 1.0), 0, 3)];
  }
  for (int b : bins)
    EXPECT_NEAR(b, 5000, 5 * std::sqrt(5000.0));  // 5 sigma
}

// Pearson's chi-square of bin counts against expected probabilities.
double chi_square(const std::vector<int>& counts, const std::vector<double>& probability) {
  double total = 0.0;
  for (int c : counts)
    total += c;
  double chi = 0.0;
  for (std::size_t k = 0; k < counts.size(); ++k) {
    const double expected = total * probability[k];
    chi += (counts[k] - expected) * (counts[k] - expected) / expected;
  }
  return chi;
}

// The density is exact, not constant per cell: on a sphere z is uniform (Archimedes), here in
// 50 bins of 20,000 expected samples. Taking |S_u x S_v| as constant over each 1/16 cell gave
// chi-square 195 for 50 bins of 2 M samples (49 expected).
TEST(Sampling, SphereIsUniformInZ) {
  Model model;
  model.surfaces.push_back(make_sphere(Vec3::Zero(), 1.0));
  constexpr int kBins = 50;
  std::vector<int> counts(kBins, 0);
  for (const SurfaceSample& s : sample_surfaces(model, 1000000, 11))
    ++counts[std::clamp(static_cast<int>((s.point.z() + 1.0) / 2.0 * kBins), 0, kBins - 1)];
  // 49 degrees of freedom: mean 49, standard deviation 9.9.
  EXPECT_LT(chi_square(counts, std::vector<double>(kBins, 1.0 / kBins)), 49 + 5 * 9.9);
}

// On a torus the density over the tube angle phi is (R + r cos phi) / (2 pi R).
TEST(Sampling, TorusFollowsItsAreaElement) {
  constexpr double R = 3.0, r = 1.0;
  Model model;
  model.surfaces.push_back(make_torus(Vec3::Zero(), R, r));
  constexpr int kBins = 36;
  const double width = 2.0 * std::numbers::pi / kBins;
  std::vector<int> counts(kBins, 0);
  for (const SurfaceSample& s : sample_surfaces(model, 1000000, 12)) {
    const double radial = std::hypot(s.point.x(), s.point.y());
    const double phi = std::atan2(s.point.z(), radial - R) + std::numbers::pi;
    ++counts[std::clamp(static_cast<int>(phi / width), 0, kBins - 1)];
  }
  std::vector<double> probability(kBins);
  for (int k = 0; k < kBins; ++k) {
    const double a = -std::numbers::pi + k * width, b = a + width;
    probability[k] = (R * width + r * (std::sin(b) - std::sin(a))) / (2.0 * std::numbers::pi * R);
  }
  EXPECT_LT(chi_square(counts, probability), 35 + 5 * 8.4);
}

// Weights multiplied by rho^i sigma^j give the same surface in another parametrization (a
// rational linear one in each direction), here with weights from 1/1728 to 1728 that squeeze the
// area into a corner of the parameter square. Uniform by area, the samples of both forms are
// distributed alike in space: compared over 6 x 6 bins of (x, y), 200,000 samples each
// (two-sample chi-square). Cells of constant density gave chi-square 5074 (35 expected).
TEST(Sampling, ExtremeWeightsDoNotChangeTheDistribution) {
  auto point = [](int i, int j) { return Vec3(i, j, 0.6 * std::sin(1.3 * i + 0.7 * j)); };
  const NurbsSurface plain = test::bicubic_patch("plain", point);
  NurbsSurface heavy = test::bicubic_patch("heavy", point);
  const double rho = 12.0, sigma = 1.0 / 12.0;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j)
      heavy.weights.push_back(std::pow(rho, i) * std::pow(sigma, j));
  }
  // The same surface: heavy(u, v) = plain(t(u), tau(v)).
  for (double u : {0.1, 0.5, 0.9}) {
    for (double v : {0.2, 0.7}) {
      const double t = rho * u / ((1 - u) + rho * u), tau = sigma * v / ((1 - v) + sigma * v);
      ASSERT_LT((heavy.evaluate(u, v) - plain.evaluate(t, tau)).norm(), 1e-12);
    }
  }
  constexpr int kBins = 6;
  auto histogram = [&](const NurbsSurface& surface, std::uint64_t seed) {
    Model model;
    model.surfaces.push_back(surface);
    std::vector<int> counts(kBins * kBins, 0);
    for (const SurfaceSample& s : sample_surfaces(model, 200000, seed)) {
      const int x = std::clamp(static_cast<int>(s.point.x() / 3.0 * kBins), 0, kBins - 1);
      const int y = std::clamp(static_cast<int>(s.point.y() / 3.0 * kBins), 0, kBins - 1);
      ++counts[x * kBins + y];
    }
    return counts;
  };
  const std::vector<int> a = histogram(plain, 21), b = histogram(heavy, 22);
  double chi = 0.0;
  for (int k = 0; k < kBins * kBins; ++k) {
    ASSERT_GT(a[k], 1000);  // every bin has area
    chi += static_cast<double>(a[k] - b[k]) * (a[k] - b[k]) / (a[k] + b[k]);
  }
  EXPECT_LT(chi, 35 + 5 * 8.4);
}

// Samples and scans are drawn in fixed chunks with their own random streams: one thread or
// several give the same points.
TEST(Sampling, SameSamplesForAnyThreadCount) {
  Model model;
  model.surfaces.push_back(make_torus(Vec3::Zero(), 3.0, 1.0));
  SyntheticScanOptions options;
  options.points = 40000;  // several chunks
  options.noise_sigma = 0.01;
  options.outlier_fraction = 0.05;
  options.seed = 5;
  std::vector<SurfaceSample> serial, parallel;
  SyntheticScan serial_scan, parallel_scan;
  {
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    serial = sample_surfaces(model, 30000, 4);
    serial_scan = make_synthetic_scan(model, options);
  }
  {
    const tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
    parallel = sample_surfaces(model, 30000, 4);
    parallel_scan = make_synthetic_scan(model, options);
  }
  ASSERT_EQ(serial.size(), parallel.size());
  for (std::size_t i = 0; i < serial.size(); ++i) {
    ASSERT_EQ(serial[i].point, parallel[i].point) << i;
    ASSERT_EQ(serial[i].normal, parallel[i].normal) << i;
  }
  ASSERT_EQ(serial_scan.points.size(), options.points);
  EXPECT_EQ(serial_scan.points, parallel_scan.points);
  EXPECT_EQ(serial_scan.on_model, parallel_scan.on_model);
}

TEST(Sampling, NormalDefinedAtPoles) {
  const NurbsSurface sphere = make_sphere(Vec3::Zero(), 1.0);
  const Vec3 north = surface_normal(sphere, 0.0, 0.3);
  EXPECT_NEAR(std::abs(north.z()), 1.0, 1e-5);
  const Vec3 south = surface_normal(sphere, 1.0, 0.7);
  EXPECT_NEAR(std::abs(south.z()), 1.0, 1e-5);
}

TEST(Sampling, TorusArea) {
  Model model;
  model.surfaces.push_back(make_torus(Vec3::Zero(), 3.0, 1.0));
  const double exact = 4.0 * std::numbers::pi * std::numbers::pi * 3.0 * 1.0;
  EXPECT_NEAR(surface_area(model), exact, 1e-6 * exact);
  // Deterministic for a seed.
  const auto a = sample_surfaces(model, 100, 42);
  const auto b = sample_surfaces(model, 100, 42);
  for (std::size_t i = 0; i < a.size(); ++i)
    EXPECT_EQ(a[i].point, b[i].point);
}

TEST(Sampling, TrimmedFaceOnly) {
  // A flat bicubic sheet S(u, v) = (4u, 4v, 0) trimmed to a square ring: outer loop
  // [0.125, 0.875]^2, hole [0.375, 0.625]^2 (even-odd), area 16 (0.75^2 - 0.25^2) = 8. Samples
  // of the trimmed-away parts would be points no projection of the face can reach.
  NurbsSurface s = test::bicubic_patch(
      "ring", [](int i, int j) { return Vec3(4.0 * i / 3.0, 4.0 * j / 3.0, 0.0); });
  s.trim_loops.push_back(
      test::polygon_loop({{0.125, 0.125}, {0.875, 0.125}, {0.875, 0.875}, {0.125, 0.875}}));
  s.trim_loops.push_back(
      test::polygon_loop({{0.375, 0.375}, {0.375, 0.625}, {0.625, 0.625}, {0.625, 0.375}}));
  Model model;
  model.surfaces.push_back(s);
  EXPECT_NEAR(surface_area(model), 8.0, 0.02 * 8.0);
  const TrimRegion region(s);
  const auto samples = sample_surfaces(model, 20000, 5);
  ASSERT_EQ(samples.size(), 20000u);
  int left = 0;
  for (const SurfaceSample& x : samples) {
    ASSERT_TRUE(region.contains(x.u, x.v)) << x.u << " " << x.v;
    EXPECT_NEAR((x.point - Vec3(4.0 * x.u, 4.0 * x.v, 0.0)).norm(), 0.0, 1e-12);
    const bool in_outer =
        x.point.x() >= 0.5 && x.point.x() <= 3.5 && x.point.y() >= 0.5 && x.point.y() <= 3.5;
    const bool in_hole =
        x.point.x() > 1.5 && x.point.x() < 2.5 && x.point.y() > 1.5 && x.point.y() < 2.5;
    EXPECT_TRUE(in_outer && !in_hole) << x.point.transpose();
    left += x.point.x() < 2.0;
  }
  // Uniform by area: the half x < 2 holds 4 of the 8 units.
  EXPECT_NEAR(left, 10000, 5 * std::sqrt(5000.0));
}

TEST(Sampling, NormalsAreOnTheFacesOuterSide) {
  // A reversed face (a CAD face whose outer side is -(S_u x S_v)): the samples' normals are the
  // ones the projector reports for the same points, here pointing into the sphere.
  Model model;
  model.surfaces.push_back(make_sphere(Vec3(1, 2, 3), 2.0));
  model.surfaces.back().reversed = true;
  const auto samples = sample_surfaces(model, 500, 3);
  const PreparedModel prepared{Model(model)};
  Projector projector(prepared);
  std::vector<Vec3> points;
  for (const SurfaceSample& x : samples)
    points.push_back(x.point);
  ProjectionResults results;
  projector.project(PointView::of(points), ProjectionOptions{}, results);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    EXPECT_NEAR(samples[i].normal.dot((samples[i].point - Vec3(1, 2, 3)).normalized()), -1.0, 1e-9);
    EXPECT_GT(samples[i].normal.dot(results.normal[i]), 1.0 - 1e-9) << i;
  }
}

TEST(Sampling, FaceWithoutAreaIsAClearError) {
  // A loop of zero area: every draw is rejected; the sampler says so instead of looping.
  Model model;
  model.surfaces.push_back(make_sphere(Vec3::Zero(), 1.0));
  NurbsSurface& s = model.surfaces.back();
  const ParamInterval du = s.domain_u(), dv = s.domain_v();
  const double u = du.lo + 0.3 * du.width(), v = dv.lo + 0.3 * dv.width();
  s.trim_loops.push_back(test::polygon_loop({{u, v}, {u + 1e-9 * du.width(), v}, {u, v}}));
  EXPECT_THROW(sample_surfaces(model, 10, 1), std::exception);
}

}  // namespace
}  // namespace nurbsreg::engine
