#include "nurbsreg/registration/alignment.hpp"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "coarse.hpp"
#include "features.hpp"
#include "nurbsreg/engine/cancellation.hpp"
#include "scan_shape.hpp"
#include "verdict.hpp"

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
  if (result.termination == IcpTermination::time_limit) {
    return fmt::format("alignment failed: {} (the pose is not final)", result.message);
  }
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
  return sizes.with_failure_note(std::move(reason));
}

}  // namespace

std::vector<std::size_t> fine_stage_sizes(std::size_t n) {
  // The first stage refines the coarse winner and makes the certificates the later passes
  // borrow: a tenth of the scan, but no more than 50,000 points, which leave a few anchors in
  // most atlas cells of the real parts (bearing: 14,800 cells from 50,000 points, 18,900 from
  // 100,000). The second stage's pose is where the first pass over all n points starts: its
  // step there is about sqrt(6 (n / m - 1)) standard deviations of the pose from all points
  // (the subsample's own uncertainty), and the pass after it stops (below one) only when that
  // step was at most about five, so m >= n / 5. Two fifths up to 200,000 points: scans of up
  // to 500,000 points keep the tenth and two fifths they always had.
  std::vector<std::size_t> sizes;
  for (const std::size_t m : {std::min<std::size_t>(n / 10, 50000),
                              std::max(n / 5, std::min<std::size_t>(n * 2 / 5, 200000))}) {
    if (m >= icp::kAutoCoarseMinPoints) sizes.push_back(m);
  }
  return sizes;
}

Aligner::Aligner(const engine::PreparedModel& model, icp::IcpOptions options,
                 RegistrationOptions registration, std::shared_ptr<const ModelFeatures> features)
    : model_(model),
      registration_(std::move(registration)),
      features_(std::move(features)),
      finder_(model),
      solver_(validated(std::move(options))) {}

const ModelFeatures& Aligner::features() {
  if (!features_) {
    try {
      features_ = std::make_shared<const ModelFeatures>(model_, registration_.global.features);
    } catch (const std::runtime_error& e) {
      throw std::invalid_argument(std::string("align: ") + e.what());
    }
  }
  return *features_;
}

AlignmentResult Aligner::align(std::span<const engine::Vec3> scan, const AlignRequest& request) {
  const bool global = request.runs_global();
  // The deadline holds for this call only (the solver is reused by the next one).
  struct DeadlineScope {
    icp::IcpSolver& solver;
    ~DeadlineScope() { solver.set_deadline(std::chrono::steady_clock::time_point::max()); }
  } scope{solver_};
  solver_.set_deadline(request.deadline);
  // Progress, likewise for this call only.
  struct ProgressScope {
    Aligner& aligner;
    ~ProgressScope() {
      aligner.progress_ = nullptr;
      aligner.solver_.set_on_iteration(nullptr);
    }
  } progress_scope{*this};
  progress_ = request.progress;
  if (progress_) solver_.set_on_iteration(icp_progress("ICP"));
  reset_projections();
  if (!global) {
    return align_from(scan, request.init.value_or(Eigen::Isometry3d::Identity()),
                      request.all_projections);
  }
  return align_global(scan, request.all_projections);
}

std::function<void(const icp::IcpIteration&)> Aligner::icp_progress(std::string what) const {
  // At most about a line a second: an alignment of a second or less says nothing more than
  // its result.
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  return [this, what = std::move(what), start, last = start](const icp::IcpIteration& it) mutable {
    const Clock::time_point now = Clock::now();
    if (!progress_ || now - last < std::chrono::seconds(1)) return;
    last = now;
    progress_(fmt::format(
        "{}: {} points, rms {:.4g} over {} inliers, step {:.3g} standard deviations ({:.1f} s "
        "so far)",
        what, it.points, it.rms, it.inliers, it.step_sigmas,
        std::chrono::duration<double>(now - start).count()));
  };
}

AlignmentResult Aligner::align(std::span<const engine::Vec3> scan, const Eigen::Isometry3d& init) {
  reset_projections();
  return align_from(scan, init, true);
}

AlignmentResult Aligner::align(std::span<const engine::Vec3> scan) {
  reset_projections();
  return align_global(scan, true);
}

void Aligner::reset_projections() {
  completed_ = false;
  scan_order_pending_ = false;
  scan_order_ready_ = false;
}

const engine::ProjectionResults& Aligner::last_projections() const {
  if (scan_order_pending_) {
    // Answer k of the ordered scan is scan point order_[k]'s. What last_projections() promises
    // (entity, u, v, distance, signed distance, status, trim edge), without feet and
    // certificates.
    scan_order_projections_.resize(order_.size(), /*feet=*/false, /*certificates=*/false);
    scan_order_projections_.scatter_from(ordered_projections(), order_);
    scan_order_pending_ = false;
    scan_order_ready_ = true;
  }
  return scan_order_ready_ ? scan_order_projections_ : ordered_projections();
}

AlignmentResult Aligner::align_from(std::span<const engine::Vec3> scan,
                                    const Eigen::Isometry3d& init, bool all_projections) {
  AlignmentResult frame;
  frame.sizes = scan_size(scan, model_);
  frame.icp = solver_.align(finder_, scan, init);
  const double noise =
      frame.icp.termination == icp::IcpTermination::invalid_input
          ? 0.0
          : detail::estimate_noise(scan, features().voxel(), registration_.global.seed);
  return finish(scan, std::move(frame), options(), noise, all_projections);
}

AlignmentResult Aligner::align_global(std::span<const engine::Vec3> scan, bool all_projections) {
  // From any pose the answer is a fresh aligner's to the bit: no certificates of the frames
  // before (keep_certificates) in the coarse stage's or the fine ICP's passes.
  // The fine ICP below runs on the scan in spatial order already (Aligner::align_global's own
  // order): the finder's would only add its cost, so it is off here too.
  struct FreshCertificates {
    icp::ModelCorrespondenceFinder& finder;
    bool keep = finder.keeps_certificates();
    bool order = finder.uses_spatial_order();
    explicit FreshCertificates(icp::ModelCorrespondenceFinder& f) : finder(f) {
      finder.keep_certificates(false);
      finder.use_spatial_order(false);
    }
    ~FreshCertificates() {
      finder.keep_certificates(keep);
      finder.use_spatial_order(order);
    }
  } fresh{finder_};
  const auto wall0 = std::chrono::steady_clock::now();
  const double cpu0 = detail::process_cpu_seconds();
  AlignmentResult frame;
  frame.sizes = scan_size(scan, model_);
  const GlobalOptions& g = registration_.global;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (!scan[i].allFinite()) {
      throw std::invalid_argument("align: scan point " + std::to_string(i) +
                                  ": non-finite coordinate");
    }
  }
  // Fewer points than any pose needs: ICP's own message says so (no place to look for).
  if (scan.size() < options().min_correspondences) {
    return align_from(scan, Eigen::Isometry3d::Identity(), all_projections);
  }
  // Stage times for `-v` (wall and this process's CPU since the previous stage).
  auto lap = [last = wall0, last_cpu = cpu0](const char* what) mutable {
    const auto now = std::chrono::steady_clock::now();
    const double cpu = detail::process_cpu_seconds();
    spdlog::debug("align: {} in {:.3f} s ({:.3f} CPU s)", what,
                  std::chrono::duration<double>(now - last).count(), cpu - last_cpu);
    last = now;
    last_cpu = cpu;
  };
  // The model's features are per model (built once, shared by batch and the service): their
  // measuring of the surface area here, like their keypoints and descriptors in the coarse
  // stage, is not the alignment's time.
  const auto area_wall0 = std::chrono::steady_clock::now();
  const double area_cpu0 = detail::process_cpu_seconds();
  const ModelFeatures& f = features();
  const double area_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - area_wall0).count();
  const double area_cpu_seconds = detail::process_cpu_seconds() - area_cpu0;
  lap("model area (once per model)");
  const double noise = detail::estimate_noise(scan, f.voxel(), g.seed);
  lap("noise estimate");
  detail::CoarseOutcome coarse =
      detail::coarse_align(scan, f, g, noise, finder_, options().deadline);
  lap("coarse stage");
  frame.coarse = std::move(coarse.report);
  frame.coarse->model_features_seconds += area_seconds;
  frame.coarse->model_features_cpu_seconds += area_cpu_seconds;
  if (coarse.failure) {
    frame.icp.T_model_scan = Eigen::Isometry3d::Identity();
    frame.icp.termination = coarse.timed_out ? icp::IcpTermination::time_limit
                                             : icp::IcpTermination::too_few_correspondences;
    frame.icp.points = scan.size();
    frame.icp.message = *coarse.failure;
    frame.failure = "alignment failed: " + *coarse.failure;
    if (coarse.found_nothing()) {
      if (const auto flat = detail::flat_scan_note(scan, noise)) *frame.failure += "; " + *flat;
    }
    frame.failure = frame.sizes.with_failure_note(std::move(*frame.failure));
    return frame;
  }
  // The fine stage from the winner: the user's options, made robust where the user left them
  // open (no kernel, no distance bound): the coarse pose is within a voxel or so, and the
  // outliers and clutter the global path is meant for must not pull it.
  icp::IcpOptions fine = options();
  if (g.robust_fine && fine.kernel == icp::RobustKernel::none) {
    fine.kernel = icp::RobustKernel::tukey;
    fine.kernel_scale = 0.0;
  }
  // Near the optimum the kernel's IRLS steps shrink by only about a sixth each: the curvature
  // steps end the full-resolution passes one pass sooner (IcpOptions::robust_newton).
  fine.robust_newton = true;
  // Outliers near the surface (clutter, a pocket's far wall) weigh nothing past the kernel's
  // cut-off: the passes on the way search only about that far (IcpOptions::kernel_bounded_search).
  fine.kernel_bounded_search = true;
  if (g.robust_fine && !std::isfinite(fine.max_correspondence_distance)) {
    fine.max_correspondence_distance = g.fine_max_distance_voxels * f.voxel();
  }
  // Only the last stage's passes touch every point: the coarse stage's pose is within a
  // fraction of a voxel, so the fine ICP starts on subsamples (fine_stage_sizes), and
  // stops on all points once its step is below g.fine_statistical_tolerance of the pose's own
  // standard deviation, at the pose of that pass (the deviations and the verdict read its
  // distances when nobody asks for the far points' projections; else they project every point
  // once more, at the returned pose).
  if (fine.coarse_sizes.empty() && fine.auto_coarse) {
    fine.coarse_sizes = fine_stage_sizes(scan.size());
  }
  // The winner is a converged short ICP's pose: the first step moves the points by about the
  // noise, far less than a certificate's radius, so the first stage's first pass makes the
  // certificates its next pass and the later stages use (else only its second pass would, and
  // the first would be one cold pass more).
  const double first_motion =
      detail::fit_tolerance(noise, frame.sizes.scan, f.voxel(), registration_.verdict);
  if (first_motion > 0.0) fine.initial_expected_motion = first_motion;
  fine.statistical_tolerance = std::max(fine.statistical_tolerance, g.fine_statistical_tolerance);
  fine.predict_final_convergence = fine.predict_final_convergence || g.fine_predict_final;
  if (progress_) {
    const CoarseReport& c = *frame.coarse;
    progress_(fmt::format(
        "coarse alignment: a pose in {:.2f} s ({:.1f}% of the points it checked fit; {} matches, "
        "{} hypotheses verified); fine ICP on {} points next",
        c.seconds, 100.0 * c.winner.inlier_fraction, c.matches, c.verified, scan.size()));
    fine.on_iteration = icp_progress("fine ICP");
  }
  // The fine ICP and the verdict run on the scan in spatial order: each pass over every point
  // reads the points' hints and writes their answers in the projector's own processing order
  // (engine::spatial_order), in sequence, where a scan in any other order (a synthetic one, a
  // merged or subsampled one) sends each of them to a random place of arrays of millions. The
  // results go back to scan order at the end (restore_scan_order).
  engine::spatial_order(engine::PointView::of(scan), order_, order_scratch_);
  ordered_scan_.resize(scan.size());
  for (std::size_t k = 0; k < scan.size(); ++k)
    ordered_scan_[k] = scan[order_[k]];
  const std::span<const engine::Vec3> ordered = ordered_scan_;
  // A solver of its own, gone with its per-point buffers (about 120 bytes a point) before the
  // verdict allocates the deviations' arrays: those then reuse memory the process has touched,
  // which on a VM whose host backs guest memory lazily costs a fraction of fresh memory.
  frame.icp = icp::IcpSolver(fine).align(finder_, ordered, frame.coarse->winner.T_model_scan);
  lap("fine ICP");
  // A continuous symmetry (a surface of revolution, a plane patch) leaves the pose free along
  // it: the pose is one of infinitely many that fit, and the report says so.
  if (frame.icp.degeneracy.degenerate()) {
    const std::string continuous = detail::describe_continuous_symmetry(
        frame.icp.degeneracy, detail::kSymmetryTextVoxels * f.voxel());
    std::string& symmetry = frame.coarse->symmetry;
    symmetry = symmetry.empty() ? continuous : continuous + "; " + symmetry;
  }
  frame = finish(ordered, std::move(frame), fine, noise, all_projections);
  restore_scan_order(scan, frame);
  lap("deviations and verdict");
  CoarseReport& c = *frame.coarse;
  c.alignment_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count() -
      c.model_features_seconds;
  c.alignment_cpu_seconds = detail::process_cpu_seconds() - cpu0 - c.model_features_cpu_seconds;
  return frame;
}

void Aligner::restore_scan_order(std::span<const engine::Vec3> scan, AlignmentResult& frame) {
  // The aligned points in place, in sequence: finish() made each as T * its ordered point, the
  // same product as T * the scan point.
  const Eigen::Isometry3d& T = frame.icp.T_model_scan;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, scan.size(), 16384),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i < r.end(); ++i)
                        frame.aligned[i] = T * scan[i];
                    });
  engine::stop_if_cancelled();  // never half the points moved
  scan_order_pending_ = true;   // the projections: on the first last_projections()
}

AlignmentResult Aligner::finish(std::span<const engine::Vec3> scan, AlignmentResult frame,
                                const icp::IcpOptions& used, double noise, bool all_projections) {
  const icp::IcpResult& result = frame.icp;
  for (const icp::IcpIteration& it : result.log) {
    spdlog::debug("stage {} rms {:.6g} inliers {}/{} step {:.3g} rad {:.3g}", it.stage, it.rms,
                  it.inliers, it.points, it.rotation_step, it.translation_step);
  }
  if (result.termination == icp::IcpTermination::invalid_input) {
    throw std::invalid_argument("align: " + result.message);
  }

  // Final per-point deviations at the solved pose (exact projections, warm-started). ICP's last
  // pass was there already when it says so and answered every point (no distance bound): its
  // projections are these (the same points, T * p in scan order), so no second pass.
  std::vector<engine::Vec3>& aligned = frame.aligned;
  aligned.resize(scan.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, scan.size(), 16384),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i < r.end(); ++i)
                        aligned[i] = result.T_model_scan * scan[i];
                    });
  // Only the deviation summary (within max_distance) and the verdict (within its tolerance)
  // read the distances unless every point's projection is asked for.
  const double mcd = used.max_correspondence_distance;
  // (Only then: features() builds the model's features when none were shared.)
  const double tolerance = all_projections
                               ? 0.0
                               : detail::fit_tolerance(noise, frame.sizes.scan, features().voxel(),
                                                       registration_.verdict);
  const double bound = all_projections ? std::numeric_limits<double>::infinity()
                                       : std::nextafter(std::max(mcd, tolerance),
                                                        std::numeric_limits<double>::infinity());
  // From any pose, ICP's bounded last pass at the returned pose (the same points, T * p in scan
  // order) answered every point within its bound exactly: the deviations and the verdict read
  // those answers, and only the points it left unanswered are projected (with the wider bound,
  // or none), so that the report's distances are the same bits with and without every
  // projection. A pass over every point would repeat those answers (the exact closest points,
  // from warmer hints, equal up to the last bits). From a given pose the pass stays, so that
  // those reports keep their bits.
  const bool at_pose = result.statistics_at_pose && finder_.last_results().size() == scan.size();
  const bool complete = frame.coarse && at_pose && std::isfinite(mcd);
  if (at_pose && std::isinf(mcd)) {
    // ICP's last pass answered every point: it is this one.
  } else if (complete) {
    const engine::ProjectionResults& icp_pass = finder_.last_results();
    far_ids_.clear();
    far_points_.clear();
    // Beyond ICP's bound the report reads distances only up to a verdict tolerance above it.
    if (all_projections || tolerance > mcd) {
      for (std::size_t i = 0; i < scan.size(); ++i) {
        if (icp_pass.status[i] == engine::ProjectionStatus::ok) continue;
        far_ids_.push_back(i);
        far_points_.push_back(aligned[i]);
      }
    }
    // With no point to add, ICP's pass itself is last_projections() (a copy of every point's
    // answer would cost a pass over fresh memory).
    if (!far_ids_.empty()) {
      completed_projections_ = icp_pass;
      correspondences_.resize(far_ids_.size());
      icp::CorrespondenceQuery query;
      query.points = far_points_;
      query.scan_indices = far_ids_;
      query.max_distance = bound;
      finder_.find(query, correspondences_);
      completed_projections_.scatter_from(finder_.last_results(), far_ids_);
      completed_ = true;
    }
  } else {
    correspondences_.resize(scan.size());
    icp::CorrespondenceQuery query;
    query.points = aligned;
    // A point with nothing of the model that near needs no exact foot.
    query.max_distance = bound;
    finder_.find(query, correspondences_);
  }
  const engine::ProjectionResults& proj = last_projections();
  const double max_distance = mcd;
  std::vector<double> inlier_distances;
  inlier_distances.reserve(scan.size());
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (proj.distance[i] <= max_distance) inlier_distances.push_back(proj.distance[i]);
  }
  frame.deviation = summarise_deviations(std::move(inlier_distances));
  frame.deviation.within = max_distance;
  frame.failure = failure_of(result, used, frame.sizes);
  if (frame.failure) return frame;

  frame.fit = detail::judge_fit(aligned, proj.distance, noise, frame.sizes.scan, features(),
                                registration_.verdict);
  if (!frame.fit.good && !registration_.verdict.accept_poor) {
    frame.failure = frame.fit.reason;
    // From a given pose the ICP runs as asked; without a robust kernel, outliers and clutter
    // pull the pose off (the global path makes its fine ICP robust by itself).
    if (!frame.coarse && used.kernel == icp::RobustKernel::none) {
      *frame.failure +=
          "; the ICP from the given pose used no robust kernel: if the scan has clutter, the "
          "tukey kernel may fit it; if not, the starting pose may be too far off";
    }
    frame.failure = frame.sizes.with_failure_note(std::move(*frame.failure));
  }
  return frame;
}

}  // namespace nurbsreg::registration
