// Symmetric parts (issue 25): when clearly different poses fit equally well, the report says so
// (the alternatives and the symmetry) instead of returning one of them silently. A saddle has
// discrete symmetries (half turns); a surface of revolution a continuous one (every rotation
// about its axis), which the final ICP names as a free rotation and the coarse report as the
// part's symmetry.
#include <gtest/gtest.h>

#include "global_support.hpp"

namespace nurbsreg::registration {
namespace {

using Eigen::Isometry3d;
using engine::Vec3;

// A saddle z = (x^2 - y^2) / 2 over [-1, 1]^2 (an exact biquadratic Bezier patch) is the same
// after a half turn about z and about the lines y = x and y = -x: four poses fit equally.
engine::Model saddle() {
  engine::NurbsSurface s;
  s.name = "saddle";
  s.degree_u = s.degree_v = 2;
  s.knots_u = s.knots_v = {0, 0, 0, 1, 1, 1};
  s.count_u = s.count_v = 3;
  s.control_points.assign(9, Vec3::Zero());
  // Bezier control net of x^2/2 over [-1, 1]: values 0.5, -0.5, 0.5 at t = 0, 0.5, 1.
  const double c[3] = {0.5, -0.5, 0.5};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      s.control_points[static_cast<std::size_t>(i * 3 + j)] =
          Vec3(20.0 * (i - 1), 20.0 * (j - 1), 20.0 * (c[i] - c[j]));
  engine::Model m;
  m.units = "mm";
  m.surfaces.push_back(std::move(s));
  return m;
}

AlignmentResult align_from_random_pose(const engine::PreparedModel& model, std::uint64_t seed) {
  engine::SyntheticScanOptions o;
  o.points = 8000;
  o.noise_sigma = 1e-4 * model.bounds().diagonal();
  std::mt19937_64 rng(seed);
  o.T_scan_model = testing::random_pose(rng, model.bounds().diagonal());
  const engine::SyntheticScan scan = engine::make_synthetic_scan(model.model(), o);
  Aligner aligner(model, icp::IcpOptions{});
  return aligner.align(scan.points);
}

TEST(Symmetry, ASaddleReportsItsHalfTurns) {
  const engine::PreparedModel model(saddle());
  const AlignmentResult r = align_from_random_pose(model, 8);
  ASSERT_TRUE(r.ok()) << *r.failure;
  ASSERT_TRUE(r.coarse);
  EXPECT_FALSE(r.coarse->alternatives.empty());
  EXPECT_NE(r.coarse->symmetry.find("rotation by 180.0 deg"), std::string::npos)
      << r.coarse->symmetry;
  // The winner is a right pose up to the part's symmetry: it maps the scan onto the model
  // within the noise.
  EXPECT_TRUE(r.fit.good);
}

TEST(Symmetry, ASurfaceOfRevolutionReportsItsAxis) {
  const engine::PreparedModel model(testing::revolved_part());
  const AlignmentResult r = align_from_random_pose(model, 12);
  ASSERT_TRUE(r.coarse);
  // Every rotation about z fits: the pose is right up to it (a good fit within the noise),
  // and the report names the axis instead of presenting one of them as the answer.
  ASSERT_TRUE(r.ok()) << *r.failure;
  EXPECT_TRUE(r.fit.good);
  EXPECT_NE(r.coarse->symmetry.find("continuous rotation about"), std::string::npos)
      << r.coarse->symmetry;
  EXPECT_TRUE(r.icp.degeneracy.degenerate());
  // The free direction is the rotation about z through the axis (0, 0, *), nothing else.
  ASSERT_EQ(r.icp.degeneracy.free_directions.size(), 1u) << r.icp.degeneracy.describe();
  const icp::FreeDirection& f = r.icp.degeneracy.free_directions.front();
  EXPECT_EQ(f.kind, icp::FreeDirection::Kind::rotation);
  EXPECT_GT(std::abs(f.direction.z()), 0.999);
  EXPECT_LT(Eigen::Vector2d(f.point.x(), f.point.y()).norm(), 0.05);
}

}  // namespace
}  // namespace nurbsreg::registration
