// Regression (issue 25): with a starting pose, the alignment is ICP exactly as before the global
// stage existed: Aligner::align(scan, init) and a request with init and the automatic mode give
// bit for bit the pose of icp::IcpSolver on the model's exact correspondences, for several
// option sets (point-to-plane, point-to-point, a robust kernel, a distance bound) and starts.
#include <gtest/gtest.h>

#include "global_support.hpp"

namespace nurbsreg::registration {
namespace {

using Eigen::Isometry3d;
using engine::Vec3;

TEST(InitRegression, AnInitGivesExactlyTheIcpPose) {
  const testing::Part& p = testing::part(testing::kPanel);
  engine::SyntheticScanOptions o;
  o.points = 4000;
  o.noise_sigma = 1e-4 * p.size;
  o.outlier_fraction = 0.1;
  o.T_scan_model = engine::pose_from_euler_degrees(3, -2, 4, Vec3(1.0, -2.0, 0.5));
  const engine::SyntheticScan scan = engine::make_synthetic_scan(p.model->model(), o);
  std::vector<icp::IcpOptions> option_sets(4);
  option_sets[1].method = icp::IcpMethod::point_to_point;
  option_sets[2].kernel = icp::RobustKernel::tukey;
  option_sets[3].max_correspondence_distance = 0.05 * p.size;
  const Isometry3d starts[] = {Isometry3d::Identity(),
                               engine::pose_from_euler_degrees(-1, 1, 2, Vec3(0.5, 0.5, 0.0))};
  for (const icp::IcpOptions& options : option_sets) {
    for (const Isometry3d& init : starts) {
      icp::ModelCorrespondenceFinder finder(*p.model);
      icp::IcpSolver solver(options);
      const icp::IcpResult plain = solver.align(finder, scan.points, init);
      Aligner aligner(*p.model, options, {}, p.features);
      const AlignmentResult direct = aligner.align(scan.points, init);
      AlignRequest request;
      request.init = init;
      const AlignmentResult requested = aligner.align(scan.points, request);
      EXPECT_EQ(direct.icp.T_model_scan.matrix(), plain.T_model_scan.matrix());
      EXPECT_EQ(requested.icp.T_model_scan.matrix(), plain.T_model_scan.matrix());
      EXPECT_EQ(direct.icp.iterations, plain.iterations);
      EXPECT_FALSE(direct.coarse.has_value()) << "the global stage ran despite an init";
    }
  }
}

}  // namespace
}  // namespace nurbsreg::registration
