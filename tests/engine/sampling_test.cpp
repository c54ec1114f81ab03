// Area-uniform sampling checked on exact shapes whose areas and normals are known.
#include <gtest/gtest.h>

#include <numbers>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/engine/shapes.hpp"
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
