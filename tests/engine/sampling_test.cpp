// Area-uniform sampling checked on exact shapes whose areas and normals are known.
#include <gtest/gtest.h>

#include <numbers>

#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/engine/shapes.hpp"

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

}  // namespace
}  // namespace nurbsreg::engine
