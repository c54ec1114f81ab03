#pragma once
// One alignment of a scan to a prepared model, as `align`, `batch`, the service and the Python
// module do it: from a starting pose, ICP on exact projections (icp::IcpSolver with an
// icp::ModelCorrespondenceFinder); without one, first the global coarse stage (global.hpp:
// features, sample consensus, hypotheses verified by exact ICP and exact distances) and then a
// robust ICP from its winner. Then the exact projections of every aligned point, their deviation
// summary, the fit verdict (good or poor, with its numbers) and the reason when the run gave no
// pose to use (an ICP failure, or a poor fit unless VerdictOptions::accept_poor). One library
// call behind every front end, so a frame gives the same numbers everywhere.
//
// Threads: one align() at a time per Aligner (it keeps the warm state of the frame before:
// per-point arrays, hints); several Aligners over one PreparedModel may run concurrently. The
// ICP inside is parallel with TBB and deterministic (results do not depend on the thread count).

#include <Eigen/Geometry>
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/spatial_order.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/registration/deviation.hpp"
#include "nurbsreg/registration/global.hpp"
#include "nurbsreg/registration/model_features.hpp"
#include "nurbsreg/registration/scan_size.hpp"

namespace nurbsreg::registration {

struct AlignmentResult {
  icp::IcpResult icp;
  // |d| of the aligned points within icp options' max_correspondence_distance.
  DeviationSummary deviation;
  std::vector<engine::Vec3> aligned;  // T_model_scan * scan point, in scan order
  ScanSize sizes;
  // Why the run gave no pose to use (ICP lost its correspondences or its normal equations broke
  // down, the coarse stage found no hypothesis, or the fit is poor and not accepted), as one
  // line for the user; nothing when the pose stands. A run that only ran out of iterations is
  // not a failure: its pose stands (termination max_iterations, converged false).
  std::optional<std::string> failure;
  // The verdict on the final pose (every alignment; not evaluated after an ICP failure).
  FitVerdict fit;
  // The global coarse stage, when it ran.
  std::optional<CoarseReport> coarse;

  bool ok() const { return !failure.has_value(); }
};

struct RegistrationOptions {
  GlobalOptions global;
  VerdictOptions verdict;
};

// What one align() call is asked: a starting pose or none, and when to run the global stage.
struct AlignRequest {
  std::optional<Eigen::Isometry3d> init;
  GlobalMode global = GlobalMode::automatic;
  // A bound on the call's wall time (a service's --time-limit): checked between the coarse
  // stage's steps and hypotheses and before every ICP iteration (icp::IcpOptions::deadline).
  // Past it the call returns a failure "time limit exceeded ..." with icp.termination
  // IcpTermination::time_limit. max(): no limit.
  std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max();
  // Every aligned point's exact projection in last_projections(), as the outputs that report
  // per-point distances need (`align --aligned`, `batch`, `inspect`, the service's and Python's
  // distances). false: only the points within the deviation summary's distance (the ICP
  // options' max_correspondence_distance) or the verdict's tolerance get one; the others are
  // left beyond_max_distance (distance NaN, entity -1) without their exact foot. The pose, the
  // deviation summary and the verdict are the same; far outliers then cost next to nothing (an
  // unbounded projection of a point far from the model searches much of it).
  bool all_projections = true;
  // Lines for a person waiting on a long alignment (`align` logs them): the coarse stage's pose
  // and time when it ends, then the ICP's progress at most about once a second (its stage's
  // points, iteration, rms and step). Called on the calling thread; empty: none.
  std::function<void(const std::string&)> progress;

  // Whether align() runs the global stage for this request (GlobalMode::on, or automatic
  // without init): the one path that needs the model's keypoints, descriptors and symmetries.
  bool runs_global() const {
    return global == GlobalMode::on || (global == GlobalMode::automatic && !init);
  }
};

// The fine ICP's subsample stages after the global stage, for a scan of n points (unless the
// options give coarse_sizes or switch auto_coarse off): a tenth of the scan up to 50,000 points,
// then two fifths up to 200,000 but at least a fifth, each only with
// icp::kAutoCoarseMinPoints or more; then all points.
std::vector<std::size_t> fine_stage_sizes(std::size_t n);

class Aligner {
 public:
  // `model` must outlive the aligner; `options` are validated (std::invalid_argument naming the
  // option otherwise). `features`: the model's coarse-stage data, shared by the aligners of one
  // model (batch workers, service sessions); null: the aligner builds its own on first need.
  Aligner(const engine::PreparedModel& model, icp::IcpOptions options,
          RegistrationOptions registration = {},
          std::shared_ptr<const ModelFeatures> features = nullptr);
  Aligner(const engine::PreparedModel&& model, icp::IcpOptions options,
          RegistrationOptions registration = {},
          std::shared_ptr<const ModelFeatures> features = nullptr) = delete;

  // Aligns `scan` (non-empty, finite points) from `init`: ICP exactly as before the global stage
  // existed (the same pose), then the verdict. Throws std::invalid_argument when ICP rejects
  // the input itself (IcpTermination::invalid_input: too few points, ...), with ICP's message.
  // Afterwards last_projections() holds the exact projections of result.aligned.
  AlignmentResult align(std::span<const engine::Vec3> scan, const Eigen::Isometry3d& init);
  // From any pose: the global coarse stage, then robust ICP from its winner, then the verdict.
  // Throws std::invalid_argument like the above, also for a scan with too few points for
  // features or a model without area.
  AlignmentResult align(std::span<const engine::Vec3> scan);
  // Either of the two, as `request` says.
  AlignmentResult align(std::span<const engine::Vec3> scan, const AlignRequest& request);

  // The exact projections of the last align()'s aligned points (entity, u, v, distance, signed
  // distance; no feet or normals), in scan order; with AlignRequest::all_projections false only
  // those of the points near the model. From any pose they are put back in scan order on the
  // first call (a pass over every point that a caller who writes no per-point output skips), so
  // the first call after an alignment must not race with another: one thread at a time, as
  // align() itself.
  const engine::ProjectionResults& last_projections() const;
  // Frames of one stream (a service session): the finder keeps its certificates from frame to
  // frame (icp::ModelCorrespondenceFinder::keep_certificates) for the frames from a pose. The
  // answers stay exact, but not bit-identical to a fresh aligner's. A frame from any pose (the
  // global stage) starts without them and is a fresh aligner's to the bit; the certificates of
  // its fine ICP serve the frames after it.
  void keep_certificates(bool keep) { finder_.keep_certificates(keep); }
  const engine::PreparedModel& model() const { return model_; }
  const icp::IcpOptions& options() const { return solver_.options(); }
  const RegistrationOptions& registration_options() const { return registration_; }
  // The model's coarse-stage data (built on first call when none was shared).
  const ModelFeatures& features();

 private:
  // The two alignments, with AlignRequest::all_projections.
  AlignmentResult align_from(std::span<const engine::Vec3> scan, const Eigen::Isometry3d& init,
                             bool all_projections);
  AlignmentResult align_global(std::span<const engine::Vec3> scan, bool all_projections);
  // Before an alignment: no projections of a previous one are served.
  void reset_projections();
  // An icp::IcpOptions::on_iteration that passes progress_ a line about once a second.
  std::function<void(const icp::IcpIteration&)> icp_progress(std::string what) const;
  AlignmentResult finish(std::span<const engine::Vec3> scan, AlignmentResult frame,
                         const icp::IcpOptions& options, double noise, bool all_projections);
  // After finish() on ordered_scan_: the aligned points and last_projections() in the order of
  // `scan` (the caller's).
  void restore_scan_order(std::span<const engine::Vec3> scan, AlignmentResult& frame);

  const engine::PreparedModel& model_;
  RegistrationOptions registration_;
  std::shared_ptr<const ModelFeatures> features_;
  icp::ModelCorrespondenceFinder finder_;
  icp::IcpSolver solver_;
  // finish()'s correspondences when it projects itself (kept: no frame-sized allocation each).
  std::vector<icp::Correspondence> correspondences_;
  // From any pose, when finish() projects the points ICP's bounded last pass left unanswered:
  // that pass's answers with theirs (completed_ true; with none to add the pass is read in place),
  // the far points and their indices (kept like correspondences_).
  engine::ProjectionResults completed_projections_;
  bool completed_ = false;
  // AlignRequest::progress for the current call (empty outside it).
  std::function<void(const std::string&)> progress_;
  std::vector<engine::Vec3> far_points_;
  std::vector<std::size_t> far_ids_;
  // From any pose: the scan in spatial order (engine::spatial_order: ordered_scan_[k] is scan
  // point order_[k]) for the fine ICP and the verdict, and their answers back in scan order.
  engine::FrameVector<std::uint32_t> order_;
  engine::SpatialOrderScratch order_scratch_;
  std::vector<engine::Vec3> ordered_scan_;
  // The answers in the spatial order above, to be put in scan order by last_projections()
  // (scan_order_pending_), and once done there (scan_order_ready_).
  const engine::ProjectionResults& ordered_projections() const {
    return completed_ ? completed_projections_ : finder_.last_results();
  }
  mutable engine::ProjectionResults scan_order_projections_;
  mutable bool scan_order_pending_ = false;
  mutable bool scan_order_ready_ = false;
};

}  // namespace nurbsreg::registration
