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
// -> solve -> update -> check convergence. See icp.cpp for the equations.
//
// Determinism: every sum over points is taken as fixed blocks of kReductionBlock points whose
// partial sums are added in block order, and selections (trimming, median) depend on values
// only, so for a deterministic finder the result is bit-identical for any number of TBB
// threads and equal to the serial path (IcpOptions::parallel = false). The library never sets
// the thread count: run it inside a tbb::task_arena or under tbb::global_control.

#include <cstddef>
#include <cstdint>
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

// IRLS weights w(r) for residual r and scale s (Zhang, "Parameter estimation techniques",
// IVC 1997, table 1; tuning constants give 95% efficiency on Gaussian noise).
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

struct IcpOptions {
  IcpMethod method = IcpMethod::point_to_plane;
  // Per stage (see coarse_sizes). >= 1.
  int max_iterations = 50;
  // Correspondences farther apart are rejected (model units, > 0; infinity: none).
  double max_correspondence_distance = std::numeric_limits<double>::infinity();
  // Trimmed ICP (Chetverikov et al., ICPR 2002): keep this fraction of the remaining
  // correspondences with the smallest distances, in (0, 1].
  double keep_fraction = 1.0;
  RobustKernel kernel = RobustKernel::none;
  // Kernel scale s (model units, >= 0). 0: re-estimated every iteration from the inlier
  // residuals as s = 1.4826 median |r| (the MAD of residuals whose centre is 0).
  double kernel_scale = 0.0;
  // Coarse-to-fine: strictly increasing subsample sizes; the solver first iterates on a
  // deterministic random subsample of each size smaller than the scan (seeded by
  // subsample_seed), then always on all points.
  std::vector<std::size_t> coarse_sizes;
  std::uint64_t subsample_seed = 1;
  // Convergence, on the applied increment (rotation [rad] about the inlier centroid and the
  // centroid's translation) ... both at or below:
  double rotation_tolerance = 1e-10;
  // model units; 0: 1e-10 x the scan's RMS radius about its centroid.
  double translation_tolerance = 0.0;
  // ... or the relative change of the inlier RMS between iterations at or below this.
  double relative_rms_tolerance = 1e-10;
  // Fewer inliers than this stops with too_few_correspondences (>= 3; 6 for a full 6-DoF
  // point-to-plane system).
  std::size_t min_correspondences = 6;
  // Eigen-directions of the scaled point-to-plane Hessian whose eigenvalue relative to the
  // largest is <= this count as unconstrained (see degeneracy.hpp); the solver does not move
  // along them. In [0, 1).
  double degeneracy_threshold = 1e-6;
  // false: every loop on the calling thread (debugging, parallel == serial tests).
  bool parallel = true;

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
  double seconds = 0.0;
};

struct IcpResult {
  Eigen::Isometry3d T_model_scan = Eigen::Isometry3d::Identity();
  IcpTermination termination = IcpTermination::invalid_input;
  std::string message;
  int iterations = 0;  // over all stages
  // Inliers: within max_correspondence_distance, kept by trimming and with robust weight > 0.
  std::size_t inliers = 0;  // at the final pose, all points
  std::size_t points = 0;   // scan size
  double rms = 0.0;         // inlier point-to-surface RMS at the final pose
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

  // Aligns `scan` (scan frame, finite coordinates) to the model behind `finder`, starting
  // from T_model_scan_init. Never throws for bad options or input: they give
  // IcpTermination::invalid_input with a message naming the field or point.
  IcpResult align(CorrespondenceFinder& finder, std::span<const engine::Vec3> scan,
                  const Eigen::Isometry3d& T_model_scan_init);

 private:
  IcpOptions options_;
  std::unique_ptr<detail::IcpBuffers> buffers_;
};

// Convenience: a fresh solver per call.
IcpResult align(CorrespondenceFinder& finder, std::span<const engine::Vec3> scan,
                const Eigen::Isometry3d& T_model_scan_init, const IcpOptions& options = {});

}  // namespace nurbsreg::icp
