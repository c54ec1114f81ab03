#pragma once
// Rigid registration of a scan to a model by ICP (Besl & McKay 1992; point-to-plane: Chen &
// Medioni 1992), with the closest-point step behind CorrespondenceFinder.
//
//   IcpSolver solver(IcpOptions{.max_correspondence_distance = 5.0});
//   IcpResult r = solver.align(finder, scan_points, Eigen::Isometry3d::Identity());
//   if (r.converged()) use(r.T_model_scan);   // model_point = T_model_scan * scan_point
//   std::puts(r.brief_report().c_str());
//
// Per iteration (IcpSolver::align): transform -> correspond -> reject -> weight -> linearize
// -> solve -> check convergence -> update (on all points, a converged run's last step is not
// applied: the result is the pose whose correspondences prove it converged, and whose statistics
// the result gives). See icp.cpp for the equations.
//
// Degenerate scans (a plane, a sphere, a cylinder, ...): the solver works in the subspace of
// rigid motions the scan constrains (eigen-decomposition of the scaled point-to-plane
// Hessian, see degeneracy.hpp) and never moves along the free directions; a run that
// converges there ends with IcpTermination::degenerate and names the free directions
// ("translation along (1, 0, 0)", "rotation about axis (0, 0, 1) through (x, y, z)").
//
// Determinism: every sum over points is taken as fixed blocks of kReductionBlock points whose
// partial sums are added in block order, and selections (trimming, median) depend on values
// only, so for a deterministic finder the result is bit-identical for any number of TBB
// threads and equal to the serial path (IcpOptions::parallel = false). The library never sets
// the thread count: run it inside a tbb::task_arena or under tbb::global_control.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "nurbsreg/icp/correspondence.hpp"
#include "nurbsreg/icp/degeneracy.hpp"
#include "nurbsreg/icp/se3.hpp"

namespace nurbsreg::icp {

// Points per block of every deterministic reduction (a constant: never the thread count).
inline constexpr std::size_t kReductionBlock = 2048;

enum class IcpMethod {
  point_to_plane,  // Gauss-Newton on SE(3) with the exact model normals (Chen & Medioni 1992)
  point_to_point,  // closed form per iteration (weighted Kabsch / Umeyama 1991)
};

// IRLS weights w(r) for residual r and scale s (Zhang, "Parameter estimation techniques: a
// tutorial with application to conic fitting", IVC 1997, section on M-estimators; the tuning
// constants give 95% asymptotic efficiency on Gaussian noise).
enum class RobustKernel {
  none,           // w = 1
  huber,          // w = 1 if |r| <= 1.345 s, else 1.345 s / |r|
  tukey,          // w = (1 - (r / 4.685 s)^2)^2 if |r| <= 4.685 s, else 0
  geman_mcclure,  // w = s^4 / (s^2 + r^2)^2 (as in Zhou et al., Fast Global Registration 2016)
};

std::string_view to_string(IcpMethod method);
std::string_view to_string(RobustKernel kernel);
// Accepts "point-to-plane" / "point_to_plane" etc.; nothing if unknown.
std::optional<IcpMethod> parse_icp_method(std::string_view text);
std::optional<RobustKernel> parse_robust_kernel(std::string_view text);

struct IcpIteration;

struct IcpOptions {
  IcpMethod method = IcpMethod::point_to_plane;
  // Per stage (see coarse_sizes). >= 1.
  int max_iterations = 50;
  // Correspondences farther apart are rejected (model units, > 0; infinity: none).
  double max_correspondence_distance = std::numeric_limits<double>::infinity();
  // Drop pairs whose foot the finder flags as on_boundary (see correspondence.hpp).
  bool reject_boundary = true;
  // Trimmed ICP (Chetverikov et al., ICPR 2002): keep this fraction of the remaining
  // correspondences with the smallest distances, in (0, 1].
  double keep_fraction = 1.0;
  RobustKernel kernel = RobustKernel::none;
  // Kernel scale s (model units, >= 0). 0: re-estimated every iteration from the inlier
  // residuals: s = 1.4826 median |r| (the MAD of residuals whose centre is 0), then iterated on
  // the residuals within 3 s only (never rising), so that outliers do not inflate it.
  double kernel_scale = 0.0;
  // With a robust kernel, point-to-plane, on all points (the last stage): once the pose is near
  // the optimum (its IRLS step within a few standard deviations, most inliers in the kernel's
  // quadratic core), the step takes the robust objective's curvature psi'(r) = (r w(r))' (where
  // it is positive) instead of the IRLS weights w(r). Both steps lead to the same estimate, but
  // IRLS gets there linearly: with Tukey's kernel and Gaussian noise, each step is about 0.17 of
  // the one before (1 - E[psi'] / E[w]), against 0.01 with the curvature. The statistics (the
  // step in standard deviations, the covariance) keep the IRLS weights. Off: IRLS steps only.
  bool robust_newton = false;
  // With Tukey's kernel (whose weight is 0 beyond c = 4.685 s), reject_boundary and no
  // trimming: every pass but the last stage's later ones searches only to twice the previous
  // pass's cut-off (plus twice the last step's motion) instead of max_correspondence_distance.
  // What is skipped is the outliers' exact feet, which near the surface (a pocket's far wall, a
  // bore, clutter on a fixture) cost a full search each and weigh 0: a kept point's residual is
  // its distance (its foot orthogonal, or on a free edge along the normal), except where Newton
  // stopped just inside a face's edge reached off its normal (then |r| < d, and such a point
  // beyond the bound is left out of those passes though its residual may weigh). A pass whose
  // cut-off comes out beyond its bound (the scale grew) is searched again to the full distance.
  // The kernel's scale is estimated without the points beyond (its first median counts fewer),
  // so the poses on the way differ in their last digits; the last stage's later passes, whose
  // answers and statistics are the result's, search to max_correspondence_distance as before.
  // Off: every pass searches to max_correspondence_distance.
  bool kernel_bounded_search = false;
  // Coarse-to-fine: strictly increasing subsample sizes; the solver first iterates on a
  // deterministic random subsample of each size smaller than the scan (seeded by
  // subsample_seed), then always on all points. The subsamples are nested (each is a prefix of
  // one random permutation of the scan), so a finder's warm-start state for a point carries
  // over to every later stage.
  std::vector<std::size_t> coarse_sizes;
  // With coarse_sizes empty: automatic levels for large scans (auto_coarse_sizes(n): n/100
  // and n/10, each only if it has >= kAutoCoarseMinPoints points). false: all points from the
  // first iteration unless coarse_sizes says otherwise.
  bool auto_coarse = true;
  std::uint64_t subsample_seed = 1;
  // Convergence, on the applied increment (rotation [rad] about the inlier centroid and the
  // centroid's translation) ... both at or below:
  double rotation_tolerance = 1e-10;
  // model units; 0: 1e-10 x the scan's RMS radius about its centroid.
  double translation_tolerance = 0.0;
  // ... or the relative change of the inlier RMS between iterations at or below this.
  double relative_rms_tolerance = 1e-10;
  // ... or the increment at or below this many standard deviations of the stage's own pose
  // estimate: its Mahalanobis length sqrt(xi^T Cov^-1 xi) with Cov = sigma^2 H^-1 (as for
  // IcpResult::covariance, on the stage's points, sigma^2 from the residuals the linearised
  // problem predicts after the step, so that misalignment is not mistaken for noise). The noise
  // leaves the pose uncertain by ~1 such unit (the error of a least-squares pose from m points with
  // residual sigma scales like sigma / sqrt(m)), so refining it further only fits the noise.
  // Dimensionless, >= 0; 0 switches it off. A noise-free scan has sigma ~ rounding, so there this
  // test only fires at the rounding level and the absolute tolerances decide.
  double statistical_tolerance = 0.1;  // the last stage (all points)
  // The same for the subsample stages: a subsample of m points cannot know the pose better
  // than ~1 of its own standard deviations, and the next stage's first step corrects the
  // remainder (it moves by ~sqrt(n_next / m) of the next stage's standard deviations anyway).
  double coarse_statistical_tolerance = 1.0;
  // Predicted convergence: ICP steps shrink geometrically near the solution (point-to-plane
  // Gauss-Newton with exact normals: a rate ~ residual x curvature, far below 1). With the
  // rate rho = |xi_k| / |xi_k-1| of the latest two steps of a stage (or of the previous stage
  // before a stage has two), a step is final when the next one, predicted as rho |xi_k|,
  // would pass the tests above (absolute or statistical). This lets the last stage end after
  // one iteration per stage from the previous stage's converged pose instead of two. The rate
  // is only trusted when rho <= 0.5 (clearly contracting).
  bool predict_convergence = true;  // subsample stages: the next stage checks the result
  // The same on the last stage (all points). Saves one full correspondence pass, but the last
  // increment is then not below tolerance itself: it is typically a few standard deviations of
  // the pose (the correction from the last subsample to all points), and the result's
  // statistics (rms, inliers, per-point results of the finder) describe the pose before it
  // (IcpResult::statistics_at_pose false). Off by default.
  bool predict_final_convergence = false;
  // Fewer inliers than this stops with too_few_correspondences (>= 3; 6 for a full 6-DoF
  // point-to-plane system).
  std::size_t min_correspondences = 6;
  // Eigen-directions of the scaled point-to-plane Hessian whose eigenvalue relative to the
  // largest is <= this count as unconstrained (see degeneracy.hpp); the solver does not move
  // along them. In [0, 1).
  double degeneracy_threshold = 1e-6;
  // How far the points are expected to move in the first step (model units; the first query's
  // CorrespondenceQuery::expected_motion, later ones take the previous step's): +infinity, any
  // move, unless the caller knows the initial pose to be that close (the global stage's refined
  // winner), so that a finder may spend work on the first pass that only nearby later queries
  // repay (certificates). Answers never depend on it; > 0.
  double initial_expected_motion = std::numeric_limits<double>::infinity();
  // false: every loop on the calling thread (debugging, parallel == serial tests).
  bool parallel = true;
  // A bound on the run's wall time (a service's per-request limit): checked once before every
  // iteration (never per point), and once past it the run stops with IcpTermination::time_limit
  // and the pose reached so far. An iteration already begun is finished, so a run may end up to
  // one iteration (plus the final statistics) after it. max(): no limit.
  std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max();
  // Called after every iteration with its IcpIteration (the entry the result's log gets), on
  // the thread that called align(): a caller's progress report. Empty: none. Its exceptions
  // propagate out of align().
  std::function<void(const IcpIteration&)> on_iteration;

  // An error naming the field (`keep_fraction: must be in (0, 1] (got 0)`), or nothing.
  std::optional<std::string> validate() const;
};

enum class IcpTermination {
  converged,                // increment or RMS change below tolerance, pose fully constrained
  degenerate,               // converged, but the free directions in `degeneracy` stay unknown
  max_iterations,           // the last stage ran out of iterations
  too_few_correspondences,  // fewer than min_correspondences inliers
  invalid_input,            // options or scan rejected (message names the field or point)
  numerical_failure,        // non-finite normal equations or pose
  time_limit,               // IcpOptions::deadline passed before convergence (not a result)
};
std::string_view to_string(IcpTermination termination);

struct IcpIteration {
  int stage = 0;               // 0 .. coarse stages, last = all points
  std::size_t points = 0;      // points used in this iteration
  std::size_t inliers = 0;     // after rejection, with weight > 0
  double rms = 0.0;            // inlier point-to-surface RMS before the update
  double kernel_scale = 0.0;   // s used for the weights (0 with RobustKernel::none)
  double rotation_step = 0.0;  // |omega| of the applied increment [rad]
  double translation_step = 0.0;
  // The increment in standard deviations of the stage's pose estimate (statistical_tolerance);
  // infinity when the residuals are all 0.
  double step_sigmas = 0.0;
  bool predicted = false;  // converged by predict_convergence rather than by the step itself
  // The step moved the pose. false only for the last iteration of a run that converged on all
  // points: its step, computed at the returned pose, is the evidence of convergence (below
  // tolerance) and is not applied, so that the result is the pose its statistics describe.
  bool applied = true;
  double seconds = 0.0;
};

struct IcpResult {
  Eigen::Isometry3d T_model_scan = Eigen::Isometry3d::Identity();
  IcpTermination termination = IcpTermination::invalid_input;
  std::string message;
  int iterations = 0;  // over all stages
  // Inliers: within max_correspondence_distance, kept by trimming and with robust weight > 0.
  // inliers, rms, covariance, degeneracy are those of the last correspondence step, on all
  // points in scan order, which was the finder's last find() (so a ModelCorrespondenceFinder's
  // last_results() are its projections). With statistics_at_pose that step was at the returned
  // pose: a converged run returns the pose of its last correspondences (the step computed there
  // is below tolerance and not applied, IcpIteration::applied), a run that ran out of
  // iterations or failed is evaluated at its returned pose once more. Otherwise (a convergence
  // predicted by predict_final_convergence, a time limit) they describe the pose before the
  // last increment.
  bool statistics_at_pose = false;
  std::size_t inliers = 0;  // all points
  std::size_t points = 0;   // scan size
  double rms = 0.0;         // inlier point-to-surface RMS
  double seconds = 0.0;
  std::vector<IcpIteration> log;
  // Covariance of the pose error as a left twist (omega [rad], v) in the model frame about
  // its origin, T_true = exp(xi) T_model_scan: sigma^2 H^+ with H the final point-to-plane
  // Hessian (also for point_to_point) and sigma^2 = sum w r^2 / sum w * n / (n - 6). In free
  // directions H^+ has no information (0): check degeneracy first.
  Mat6 covariance = Mat6::Zero();
  DegeneracyReport degeneracy;

  bool converged() const { return termination == IcpTermination::converged; }
  // One line, e.g. "converged after 6 iterations (0.01 s): rms 0.0012 over 2950/3000 inliers".
  std::string brief_report() const;
};

namespace detail {
struct IcpBuffers;  // per-point work arrays, defined in icp.cpp
}

// Holds options and the per-point buffers, which are reused by later calls (so a sequence of
// frames allocates only when a scan is larger than any before). One align() at a time per
// solver; distinct solvers are independent.
class IcpSolver {
 public:
  explicit IcpSolver(IcpOptions options = {});
  ~IcpSolver();
  IcpSolver(IcpSolver&&) noexcept;
  IcpSolver& operator=(IcpSolver&&) noexcept;
  const IcpOptions& options() const { return options_; }
  // Sets options().deadline for the calls that follow (a per-request limit for a reused
  // solver).
  void set_deadline(std::chrono::steady_clock::time_point deadline) {
    options_.deadline = deadline;
  }
  // Sets options().on_iteration for the calls that follow (a reused solver's per-call progress).
  void set_on_iteration(std::function<void(const IcpIteration&)> on_iteration) {
    options_.on_iteration = std::move(on_iteration);
  }

  // Aligns `scan` (scan frame, finite coordinates) to the model behind `finder`, starting
  // from T_model_scan_init. Never throws for bad options or input: they give
  // IcpTermination::invalid_input with a message naming the field or point. Exceptions from
  // the finder propagate.
  IcpResult align(CorrespondenceFinder& finder, std::span<const engine::Vec3> scan,
                  const Eigen::Isometry3d& T_model_scan_init);

 private:
  IcpOptions options_;
  std::unique_ptr<detail::IcpBuffers> buffers_;
};

// Points below which a level of the automatic coarse-to-fine schedule is not used (a pose
// from fewer points is too noisy to save the next level an iteration).
inline constexpr std::size_t kAutoCoarseMinPoints = 2000;
// The subsample sizes the solver uses for a scan of n points: options.coarse_sizes if not
// empty, else the automatic levels (auto_coarse), else none. All are < n.
std::vector<std::size_t> coarse_schedule(const IcpOptions& options, std::size_t n);

// Convenience: a fresh solver per call.
IcpResult align(CorrespondenceFinder& finder, std::span<const engine::Vec3> scan,
                const Eigen::Isometry3d& T_model_scan_init, const IcpOptions& options = {});

}  // namespace nurbsreg::icp
