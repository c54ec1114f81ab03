#pragma once
// One alignment of a scan to a prepared model, as `align`, `batch`, the service and the Python
// module do it: ICP on exact projections (icp::IcpSolver with an icp::ModelCorrespondenceFinder)
// from a starting pose, then the exact projections of every aligned point and their deviation
// summary, and the reason when the run gave no pose to use. One library call behind every
// front end, so a frame gives the same numbers everywhere.
//
// Threads: one align() at a time per Aligner (it keeps the warm state of the frame before:
// per-point arrays, hints); several Aligners over one PreparedModel may run concurrently. The
// ICP inside is parallel with TBB and deterministic (results do not depend on the thread count).

#include <Eigen/Geometry>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/registration/deviation.hpp"
#include "nurbsreg/registration/scan_size.hpp"

namespace nurbsreg::registration {

struct AlignmentResult {
  icp::IcpResult icp;
  // |d| of the aligned points within icp options' max_correspondence_distance.
  DeviationSummary deviation;
  std::vector<engine::Vec3> aligned;  // T_model_scan * scan point, in scan order
  ScanSize sizes;
  // Why the run gave no pose to use (ICP lost its correspondences or its normal equations broke
  // down), as one line for the user; nothing when the pose stands. A run that only ran out of
  // iterations is not a failure: its pose stands (termination max_iterations, converged false).
  std::optional<std::string> failure;

  bool ok() const { return !failure.has_value(); }
};

class Aligner {
 public:
  // `model` must outlive the aligner; `options` are validated (std::invalid_argument naming the
  // option otherwise).
  Aligner(const engine::PreparedModel& model, icp::IcpOptions options);
  Aligner(const engine::PreparedModel&& model, icp::IcpOptions options) = delete;

  // Aligns `scan` (non-empty, finite points) from `init`. Throws std::invalid_argument when ICP
  // rejects the input itself (IcpTermination::invalid_input: too few points, ...), with ICP's
  // message. Afterwards last_projections() holds the exact projections of result.aligned.
  AlignmentResult align(std::span<const engine::Vec3> scan, const Eigen::Isometry3d& init);

  // The exact projections of the last align()'s aligned points (entity, u, v, distance, signed
  // distance; no feet or normals), in scan order.
  const engine::ProjectionResults& last_projections() const { return finder_.last_results(); }
  const engine::PreparedModel& model() const { return model_; }
  const icp::IcpOptions& options() const { return solver_.options(); }

 private:
  const engine::PreparedModel& model_;
  icp::ModelCorrespondenceFinder finder_;
  icp::IcpSolver solver_;
};

}  // namespace nurbsreg::registration
