#include "nurbsreg/io/alignment_result_report.hpp"

#include <string>

namespace nurbsreg::io {

AlignmentReport make_alignment_report(const registration::AlignmentResult& frame,
                                      icp::IcpMethod method, std::size_t skipped_points,
                                      double seconds) {
  const icp::IcpResult& result = frame.icp;
  AlignmentReport report;
  report.pose = result.T_model_scan.matrix();
  report.rms = result.rms;
  report.iterations = result.iterations;
  // A degenerate scan converges within the directions it constrains; the termination text
  // names the free ones.
  report.converged = result.converged() || result.termination == icp::IcpTermination::degenerate;
  report.inliers = result.inliers;
  report.points = result.points;
  report.skipped_points = skipped_points;
  report.seconds = seconds;
  report.method = std::string(icp::to_string(method));
  report.termination = std::string(icp::to_string(result.termination)) + ": " + result.message;
  if (result.degeneracy.degenerate()) {
    report.termination += "; free directions: " + result.degeneracy.describe();
  }
  int k = 0;
  for (const icp::IcpIteration& it : result.log) {
    report.history.push_back(
        {++k, it.rms, it.inliers, it.rotation_step, it.translation_step, it.seconds});
  }
  return report;
}

}  // namespace nurbsreg::io
