// Align a scan to a model by ICP on exact closest points. The scan is synthetic (a known pose,
// noise along the normal), so the program can say how far the estimate is from the truth.
#include <cmath>
#include <cstdio>
#include <exception>
#include <numbers>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/io/model_file.hpp"
using namespace nurbsreg;

int main(int argc, char** argv) try {
  const char* file = argc > 1 ? argv[1] : "examples/panel.json";
  const engine::Model cad = io::read_model_file(file);

  // 20,000 points seen from a scanner 2 degrees and 1.5 mm away, 0.01 mm of noise.
  engine::SyntheticScanOptions synth;
  synth.points = 20000;
  synth.noise_sigma = 0.01;
  synth.T_scan_model = engine::pose_from_euler_degrees(1.0, -1.5, 0.5, {1.0, -0.8, 0.6});
  const engine::SyntheticScan scan = engine::make_synthetic_scan(cad, synth);

  const engine::PreparedModel model(cad);  // prepared once, then shared by every iteration
  icp::ModelCorrespondenceFinder finder(model);
  icp::IcpOptions options;
  options.max_correspondence_distance = 20.0;  // mm: above every pair's initial distance
  icp::IcpSolver solver(options);
  const icp::IcpResult r = solver.align(finder, scan.points, Eigen::Isometry3d::Identity());
  std::printf("%s\n", r.brief_report().c_str());
  if (!r.converged()) return 1;

  // model_point = T_model_scan * scan_point; the error is what is left of the true pose.
  const Eigen::Isometry3d error = scan.T_model_scan.inverse() * r.T_model_scan;
  const double degrees = Eigen::AngleAxisd(error.rotation()).angle() * 180.0 / std::numbers::pi;
  std::printf("pose error: %.6f deg, %.6f mm\n", degrees, error.translation().norm());
} catch (const std::exception& e) {
  std::fprintf(stderr, "error: %s\n", e.what());
  return 3;
}
