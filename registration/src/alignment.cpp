#include "nurbsreg/registration/alignment.hpp"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <stdexcept>

namespace nurbsreg::registration {
namespace {

icp::IcpOptions validated(icp::IcpOptions options) {
  if (auto error = options.validate()) throw std::invalid_argument(*error);
  return options;
}

// Why the result gives no pose to use, or nothing (AlignmentResult::failure).
std::optional<std::string> failure_of(const icp::IcpResult& result, const icp::IcpOptions& options,
                                      const ScanSize& sizes) {
  using icp::IcpTermination;
  if (result.termination != IcpTermination::too_few_correspondences &&
      result.termination != IcpTermination::numerical_failure) {
    return std::nullopt;
  }
  std::string reason =
      fmt::format("alignment failed after {} iterations: {} ({})", result.iterations,
                  icp::to_string(result.termination), result.message);
  // A scan with fewer points than a pose needs fails wherever it lies: no hint about its place.
  const bool scan_too_small = result.points < options.min_correspondences;
  if (result.termination == IcpTermination::too_few_correspondences && !scan_too_small) {
    reason += "; is the scan near the model? Give a starting pose (--init)";
    if (std::isfinite(options.max_correspondence_distance)) reason += " or a larger --max-distance";
  }
  if (const auto note = sizes.failure_note()) reason += "; " + *note;
  return reason;
}

}  // namespace

Aligner::Aligner(const engine::PreparedModel& model, icp::IcpOptions options)
    : model_(model), finder_(model), solver_(validated(std::move(options))) {}

AlignmentResult Aligner::align(std::span<const engine::Vec3> scan, const Eigen::Isometry3d& init) {
  AlignmentResult frame;
  frame.sizes = scan_size(scan, model_);
  frame.icp = solver_.align(finder_, scan, init);
  const icp::IcpResult& result = frame.icp;
  for (const icp::IcpIteration& it : result.log) {
    spdlog::debug("stage {} rms {:.6g} inliers {}/{} step {:.3g} rad {:.3g}", it.stage, it.rms,
                  it.inliers, it.points, it.rotation_step, it.translation_step);
  }
  if (result.termination == icp::IcpTermination::invalid_input) {
    throw std::invalid_argument("align: " + result.message);
  }

  // Final per-point deviations at the solved pose (exact projections, warm-started).
  std::vector<engine::Vec3>& aligned = frame.aligned;
  aligned.resize(scan.size());
  for (std::size_t i = 0; i < scan.size(); ++i)
    aligned[i] = result.T_model_scan * scan[i];
  std::vector<icp::Correspondence> correspondences(scan.size());
  icp::CorrespondenceQuery query;
  query.points = aligned;
  finder_.find(query, correspondences);
  const engine::ProjectionResults& proj = finder_.last_results();
  const double max_distance = options().max_correspondence_distance;
  std::vector<double> inlier_distances;
  inlier_distances.reserve(scan.size());
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (proj.distance[i] <= max_distance) inlier_distances.push_back(proj.distance[i]);
  }
  frame.deviation = summarise_deviations(std::move(inlier_distances));
  frame.failure = failure_of(result, options(), frame.sizes);
  return frame;
}

}  // namespace nurbsreg::registration
