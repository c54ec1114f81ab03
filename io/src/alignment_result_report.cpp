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
  if (frame.fit.evaluated) {
    const registration::FitVerdict& f = frame.fit;
    report.has_fit = true;
    report.fit = {std::string(f.word()), f.reason,   f.noise,     f.tolerance,
                  f.inlier_fraction,     f.rms,      f.rms_ratio, f.coverage,
                  f.scan_noise,          f.fit_noise};
  }
  if (const auto& c = frame.coarse) {
    const auto score = [](const registration::PoseScore& s) {
      return PoseScoreRecord{s.T_model_scan.matrix(), s.inlier_fraction, s.trimmed_rms};
    };
    report.has_coarse = true;
    CoarseRecord& r = report.coarse;
    r.method = c->method;
    r.scan_keypoints = c->scan_keypoints;
    r.model_keypoints = c->model_keypoints;
    r.matches = c->matches;
    r.hypotheses = c->hypotheses;
    r.verified = c->verified;
    r.voxel = c->voxel;
    r.noise = c->noise;
    r.seconds = c->seconds;
    r.model_features_seconds = c->model_features_seconds;
    r.alignment_seconds = c->alignment_seconds;
    r.alignment_cpu_seconds = c->alignment_cpu_seconds;
    r.winner = score(c->winner);
    r.has_runner_up = c->runner_up.has_value();
    if (c->runner_up) r.runner_up = score(*c->runner_up);
    for (const registration::PoseScore& a : c->alternatives)
      r.alternatives.push_back(score(a));
    r.symmetry = c->symmetry;
  }
  int k = 0;
  for (const icp::IcpIteration& it : result.log) {
    report.history.push_back(
        {++k, it.rms, it.inliers, it.rotation_step, it.translation_step, it.seconds});
  }
  return report;
}

}  // namespace nurbsreg::io
