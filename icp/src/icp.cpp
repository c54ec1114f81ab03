// The ICP loop. Notation: scan point p_i, current pose T (model <- scan), moved point
// q_i = T p_i, foot f_i and unit normal n_i on the model, weight w_i, inlier centroid c,
// linearisation centre c' (see decouple()), length scale L (RMS radius of the scan about its
// centroid). Allocation: only the buffers in detail::IcpBuffers (grown, never shrunk), the
// per-stage index list and the iteration log; nothing per point.
#include "nurbsreg/icp/icp.hpp"

#include "blocks.hpp"
#include "nurbsreg/engine/large_buffer.hpp"
#include "nurbsreg/engine/point_extent.hpp"

#include <spdlog/spdlog.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <optional>
#include <random>

namespace nurbsreg::icp {
namespace {

using Eigen::Isometry3d;
using Eigen::Matrix3d;
using engine::Vec3;
using Clock = std::chrono::steady_clock;
using detail::for_each_block;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::size_t block_count(std::size_t n) {
  return (n + kReductionBlock - 1) / kReductionBlock;
}

// Partial sums of one block.
struct Moments {
  // Point-to-plane normal equations in scaled coordinates xi_s = (L omega, v).
  Mat6 H = Mat6::Zero();
  Vec6 g = Vec6::Zero();
  double sum_w = 0.0;
  double sum_wr2 = 0.0;
  // IcpOptions::robust_newton: H with the kernel's curvature max(psi'(r), 0) instead of w(r),
  // and the sum of those weights.
  Mat6 H_curvature = Mat6::Zero();
  double sum_curvature = 0.0;
  // Weighted moments about c for the closed-form point-to-point step: a = q - c, b = f - c.
  Vec3 sum_wa = Vec3::Zero();
  Vec3 sum_wb = Vec3::Zero();
  Matrix3d sum_wba = Matrix3d::Zero();  // sum w b a^T

  void add(const Moments& o) {
    H += o.H;
    g += o.g;
    sum_w += o.sum_w;
    sum_wr2 += o.sum_wr2;
    H_curvature += o.H_curvature;
    sum_curvature += o.sum_curvature;
    sum_wa += o.sum_wa;
    sum_wb += o.sum_wb;
    sum_wba += o.sum_wba;
  }
};

struct Centroid {
  Vec3 sum = Vec3::Zero();
  std::size_t count = 0;
};

struct LinearSystem {
  Moments m;  // H, g about `center`; point-to-point moments about `centroid`
  std::size_t count = 0;
  Vec3 centroid = Vec3::Zero();  // inlier centroid c
  Vec3 center = Vec3::Zero();    // linearisation and update centre c' (see decouple())
  double length_scale = 1.0;
};

struct Rejection {
  std::size_t inliers = 0;
  double rms = 0.0;
};

// Increment (omega, v) about the centre c': q -> c' + exp(omega) (q - c') + v (update_pose).
struct Step {
  Vec6 xi = Vec6::Zero();
  double scaled_norm = 0.0;  // |xi_s|, xi_s = (L omega, v)
  double sigmas = 0.0;       // Mahalanobis length sqrt(xi_s^T H_s xi_s) / sigma
  double sigma2 = 0.0;       // residual variance after the step (residual_variance)
  bool finite = true;
};

// Residual variance sigma^2 = ssr / sum w * n / (n - 6) (6 fitted parameters) for a weighted
// sum of squared residuals ssr; 0 when it cannot be estimated.
double residual_variance(const LinearSystem& sys, double ssr) {
  const double n = static_cast<double>(sys.count);
  if (sys.count <= 6 || !(sys.m.sum_w > 0.0)) return 0.0;
  return std::max(0.0, ssr) / sys.m.sum_w * n / (n - 6.0);
}

}  // namespace

namespace detail {
struct IcpBuffers {
  // Per-point arrays: faulted in on all threads for large scans (engine/large_buffer.hpp).
  engine::FrameVector<std::size_t> ids;  // active scan indices, ascending
  engine::FrameVector<Vec3> moved;       // q_i
  engine::FrameVector<Correspondence> matches;
  engine::FrameVector<std::uint8_t> inlier;
  engine::FrameVector<double> residual;
  engine::FrameVector<double> weight;
  engine::FrameVector<double> scratch;  // selections (trimming, median)
  std::vector<Moments> moment_blocks;
  std::vector<Centroid> centroid_blocks;

  void resize(std::size_t n) {
    moved.resize(n);
    matches.resize(n);
    inlier.resize(n);
    residual.resize(n);
    weight.resize(n);
    moment_blocks.resize(block_count(n));
    centroid_blocks.resize(block_count(n));
  }
};
}  // namespace detail

namespace {

using Buffers = detail::IcpBuffers;

// The active points of a stage: all of them, or a deterministic uniform random subsample
// (partial Fisher-Yates on std::mt19937_64, which the standard specifies bit for bit), sorted
// so that the finder reads the scan in memory order. The swaps do not depend on m, so for one
// seed the subsample of size m is contained in every larger one (nested levels).
void select_points(std::size_t n, std::size_t m, std::uint64_t seed,
                   engine::FrameVector<std::size_t>& ids) {
  ids.resize(n);
  std::iota(ids.begin(), ids.end(), std::size_t{0});
  if (m >= n) return;
  std::mt19937_64 rng(seed);
  for (std::size_t i = 0; i < m; ++i) {
    std::swap(ids[i], ids[i + static_cast<std::size_t>(rng() % (n - i))]);
  }
  ids.resize(m);
  std::sort(ids.begin(), ids.end());
}

// Step 1, transform: q_i = T p_i.
void transform_points(const Isometry3d& T, std::span<const Vec3> scan, Buffers& b, bool parallel) {
  for_each_block(b.ids.size(), parallel, [&](std::size_t begin, std::size_t end, std::size_t) {
    for (std::size_t k = begin; k < end; ++k)
      b.moved[k] = T * scan[b.ids[k]];
  });
}

// Step 2, correspond: f_i, n_i, d_i = |q_i - f_i| from the model's closest-point step.
void find_correspondences(CorrespondenceFinder& finder, double max_distance, bool parallel,
                          double expected_motion, int later_queries, Buffers& b) {
  CorrespondenceQuery query;
  query.later_queries = later_queries;
  query.points = b.moved;
  query.scan_indices = b.ids;
  query.max_distance = max_distance;
  query.parallel = parallel;
  query.expected_motion = expected_motion;
  finder.find(query, b.matches);
}

// Why a correspondence is rejected before trimming and weighting: no foot within the maximum
// distance, or a foot beyond a free edge of the model (reject_boundary); none: it may be an inlier.
// The one rule for reject_outliers and for rejection_summary's counts.
enum class Cut { none, too_far, beyond_edge };
Cut cut_of(const IcpOptions& o, const Correspondence& c) {
  if (!c.valid || !std::isfinite(c.distance) || !(c.distance <= o.max_correspondence_distance)) {
    return Cut::too_far;
  }
  return o.reject_boundary && c.on_boundary ? Cut::beyond_edge : Cut::none;
}

// Step 3, reject: valid, d_i <= max distance, foot not beyond a free boundary (if asked), then
// Trimmed ICP (Chetverikov et al. 2002): keep the
// ceil(keep_fraction * m) smallest distances (all ties of the cut value, so the set depends
// on the values only).
void reject_outliers(const IcpOptions& o, Buffers& b) {
  const double keep_fraction = o.keep_fraction;
  const std::size_t n = b.ids.size();
  for_each_block(n, o.parallel, [&](std::size_t begin, std::size_t end, std::size_t) {
    for (std::size_t k = begin; k < end; ++k)
      b.inlier[k] = cut_of(o, b.matches[k]) == Cut::none ? 1 : 0;
  });
  if (keep_fraction < 1.0) {
    b.scratch.clear();
    for (std::size_t k = 0; k < n; ++k) {
      if (b.inlier[k]) b.scratch.push_back(b.matches[k].distance);
    }
  }
  if (keep_fraction < 1.0 && !b.scratch.empty()) {
    const std::size_t keep = std::max<std::size_t>(
        1,
        static_cast<std::size_t>(std::ceil(keep_fraction * static_cast<double>(b.scratch.size()))));
    std::nth_element(b.scratch.begin(), b.scratch.begin() + static_cast<std::ptrdiff_t>(keep - 1),
                     b.scratch.end());
    const double cut = b.scratch[keep - 1];
    for (std::size_t k = 0; k < n; ++k) {
      if (b.inlier[k] && b.matches[k].distance > cut) b.inlier[k] = 0;
    }
  }
}

// Why the points of an iteration are not inliers, for too_few_correspondences' message: a user
// whose scan lost its correspondences needs to know whether it is too far from the model, beyond
// its edges, or cut by trimming and the robust kernel.
std::string rejection_summary(const IcpOptions& o, const Buffers& b) {
  std::size_t too_far = 0, beyond_edge = 0, inliers = 0;
  for (std::size_t k = 0; k < b.ids.size(); ++k) {
    if (b.inlier[k]) {
      ++inliers;
      continue;
    }
    const Cut cut = cut_of(o, b.matches[k]);
    too_far += cut == Cut::too_far;
    beyond_edge += cut == Cut::beyond_edge;
  }
  const std::size_t weighted_out = b.ids.size() - inliers - too_far - beyond_edge;
  return std::to_string(too_far) + " farther than max_correspondence_distance, " +
         std::to_string(beyond_edge) + " beyond the model's free edges, " +
         std::to_string(weighted_out) + " trimmed or weighted out";
}

// Inlier count and RMS of d_i over the inliers (serial sum in index order: one cheap pass).
Rejection inlier_statistics(const Buffers& b) {
  Rejection r;
  double sum = 0.0;
  for (std::size_t k = 0; k < b.ids.size(); ++k) {
    if (!b.inlier[k]) continue;
    ++r.inliers;
    sum += b.matches[k].distance * b.matches[k].distance;
  }
  r.rms = r.inliers > 0 ? std::sqrt(sum / static_cast<double>(r.inliers)) : 0.0;
  return r;
}

// Tukey's cut-off c = 4.685 s: beyond it a residual weighs 0 (kernel_weight).
double tukey_cutoff(double scale) {
  return 4.685 * scale;
}

// IRLS weight for residual r and scale s (Zhang 1997, M-estimators).
double kernel_weight(RobustKernel kernel, double r, double s) {
  const double a = std::abs(r);
  switch (kernel) {
    case RobustKernel::none:
      return 1.0;
    case RobustKernel::huber: {
      const double k = 1.345 * s;
      return a <= k ? 1.0 : k / a;
    }
    case RobustKernel::tukey: {
      const double c = tukey_cutoff(s);
      if (a >= c) return 0.0;
      const double u = 1.0 - (a / c) * (a / c);
      return u * u;
    }
    case RobustKernel::geman_mcclure: {
      const double d = s * s + r * r;
      return s * s * s * s / (d * d);
    }
  }
  return 1.0;
}

// The robust objective's curvature psi'(r) = d(r w(r)) / dr where it is positive, 0 elsewhere
// (beyond Huber's corner; for Tukey past |r| = c / sqrt(5); for Geman-McClure past
// |r| = s / sqrt(3)): the Newton weight of IcpOptions::robust_newton, positive semi-definite.
double kernel_curvature(RobustKernel kernel, double r, double s) {
  const double a = std::abs(r);
  switch (kernel) {
    case RobustKernel::none:
      return 1.0;
    case RobustKernel::huber:
      return a <= 1.345 * s ? 1.0 : 0.0;
    case RobustKernel::tukey: {
      const double c = tukey_cutoff(s);
      if (a >= c) return 0.0;
      const double u2 = (a / c) * (a / c);
      return std::max(0.0, (1.0 - u2) * (1.0 - 5.0 * u2));
    }
    case RobustKernel::geman_mcclure: {
      const double s2 = s * s, d = s2 + r * r;
      return std::max(0.0, s2 * s2 * (s2 - 3.0 * r * r) / (d * d * d));
    }
  }
  return 1.0;
}

// The scale of the inliers' residuals |r| (reordered in place): 1.4826 median |r| (the MAD
// about 0, consistent for Gaussian noise), then re-estimated from the residuals within 3 times
// the current scale only, until it settles. The plain MAD follows the outliers it is meant to
// reject: with 30% gross outliers it sits at the 71st percentile of the inliers' |r|, 1.6 sigma,
// and the kernel's cut-off moves out with it. Each round's median counts only |r| <= 3 s, with
// the factor that keeps it consistent for Gaussian noise truncated at 3 sigma (the median of
// |N(0, 1)| given |N| <= 3 is 0.6725: 1.4870 = 1 / 0.6725). A hard cap: a round never raises
// the scale, so a cluster of outliers near the cut-off cannot pull it back out.
double robust_scale(engine::FrameVector<double>& abs_residuals) {
  auto& r = abs_residuals;
  if (r.empty()) return 0.0;
  auto mid = r.begin() + static_cast<std::ptrdiff_t>((r.size() - 1) / 2);
  std::nth_element(r.begin(), mid, r.end());
  double scale = 1.4826 * *mid;
  for (int round = 0; round < 8 && scale > 0.0; ++round) {
    const double cut = 3.0 * scale;
    const auto end = std::partition(r.begin(), r.end(), [&](double x) { return x <= cut; });
    const std::size_t kept = static_cast<std::size_t>(end - r.begin());
    if (kept < 2) break;
    mid = r.begin() + static_cast<std::ptrdiff_t>((kept - 1) / 2);
    std::nth_element(r.begin(), mid, end);
    const double next = std::min(scale, 1.4870 * *mid);
    const bool settled = next >= 0.999 * scale;
    scale = next;
    if (settled) break;
  }
  return scale;
}

// Step 4, weight: residuals r_i (point-to-plane: n_i . (q_i - f_i), the linearised distance
// of Chen & Medioni; point-to-point: d_i) and IRLS weights w_i = w(r_i; s). With an automatic
// scale s = robust_scale of the inliers' |r_i| (an iterated, truncated MAD), floored
// at 1e-12 L so that an exact fit (all r = 0) keeps unit weights. Points whose weight is 0
// (beyond Tukey's cut-off) stop counting as inliers. Returns s (0: no kernel).
double compute_weights(const IcpOptions& o, double length_scale, Buffers& b) {
  const std::size_t n = b.ids.size();
  for_each_block(n, o.parallel, [&](std::size_t begin, std::size_t end, std::size_t) {
    for (std::size_t k = begin; k < end; ++k) {
      const Correspondence& c = b.matches[k];
      b.residual[k] = !b.inlier[k]                            ? 0.0
                      : o.method == IcpMethod::point_to_plane ? c.normal.dot(b.moved[k] - c.foot)
                                                              : c.distance;
      if (o.kernel == RobustKernel::none) b.weight[k] = b.inlier[k] ? 1.0 : 0.0;
    }
  });
  if (o.kernel == RobustKernel::none) return 0.0;
  double scale = o.kernel_scale;
  if (scale == 0.0) {
    b.scratch.clear();
    if (std::none_of(b.inlier.begin(), b.inlier.begin() + static_cast<std::ptrdiff_t>(n),
                     [](std::uint8_t x) { return x != 0; })) {
      return 0.0;
    }
    for (std::size_t k = 0; k < n; ++k) {
      if (b.inlier[k]) b.scratch.push_back(std::abs(b.residual[k]));
    }
    scale = std::max(robust_scale(b.scratch), 1e-12 * length_scale);
  }
  for (std::size_t k = 0; k < n; ++k) {
    b.weight[k] = b.inlier[k] ? kernel_weight(o.kernel, b.residual[k], scale) : 0.0;
    if (b.weight[k] <= 0.0) b.inlier[k] = 0;
  }
  return scale;
}

// Moves the linearisation centre from c to the point c' = c + d about which rotations and
// translations are least coupled: the "centre of stiffness" that makes the off-diagonal block
// sum w ((q - c') x n / L) n^T of H_s vanish in the least-squares sense. With
// J'_s = T J_s, T = [I, -[d]x / L; 0, I], the block becomes H_rt - [d]x H_tt / L, so d solves
// [d]x N_k = L C_k for the columns k of N = H_tt, C = H_rt, the minimum-norm solution when
// that is underdetermined. Full-rank Gauss-Newton steps do not depend on the centre (to first
// order), but the split into free and constrained directions does: about c' a sphere's free
// motions are pure rotations about its centre, orthogonal to every translation, so the
// constrained step translates without rotating (and a plane's c' stays at c).
void decouple(LinearSystem& sys) {
  const double L = sys.length_scale;
  const Matrix3d C = sys.m.H.topRightCorner<3, 3>();
  const Matrix3d N = sys.m.H.bottomRightCorner<3, 3>();
  Eigen::Matrix<double, 9, 3> M;
  Eigen::Matrix<double, 9, 1> rhs;
  for (int k = 0; k < 3; ++k) {
    M.block<3, 3>(3 * k, 0) = -skew(N.col(k));
    rhs.segment<3>(3 * k) = L * C.col(k);
  }
  Eigen::JacobiSVD<Eigen::Matrix<double, 9, 3>> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  svd.setThreshold(1e-9);
  const Vec3 d = svd.solve(rhs);
  // A centre far outside the scan means the decoupling is numerically meaningless: keep c.
  if (!d.allFinite() || d.norm() > 1e3 * L) return;
  Mat6 T = Mat6::Identity();
  T.topRightCorner<3, 3>() = -skew(d) / L;
  sys.m.H = T * sys.m.H * T.transpose();
  sys.m.H_curvature = T * sys.m.H_curvature * T.transpose();
  sys.m.g = T * sys.m.g;
  sys.center = sys.centroid + d;
}

// Step 5, linearize. A left increment about the inlier centroid c moves q to
// q + omega x (q - c) + v, so the point-to-plane residual becomes (Chen & Medioni 1992;
// small-angle linearisation as in Low, UNC TR04-004, 2004)
//   r_i(xi) = n_i . (q_i - f_i) + ((q_i - c) x n_i) . omega + n_i . v = r_i + J_i^T xi,
// and in scaled coordinates xi_s = (L omega, v): J_s,i = [(q_i - c) x n_i / L ; n_i].
// Weighted Gauss-Newton normal equations H_s = sum w J_s J_s^T, g_s = sum w J_s r (IRLS),
// reduced by blocks.
// The point-to-point moments about c are collected in the same pass when the step needs them
// (point_moments: only solve()'s point-to-point branch reads them); then the centre moves to c'
// (decouple()).
LinearSystem linearize(double length_scale, bool parallel, bool point_moments, Buffers& b,
                       RobustKernel curvature_kernel = RobustKernel::none,
                       double kernel_scale = 0.0) {
  // IcpOptions::robust_newton: the curvature-weighted H too (RobustKernel::none: not wanted).
  const bool curvature = curvature_kernel != RobustKernel::none && kernel_scale > 0.0;
  const std::size_t n = b.ids.size();
  LinearSystem sys;
  sys.length_scale = length_scale;
  for_each_block(n, parallel, [&](std::size_t begin, std::size_t end, std::size_t block) {
    Centroid part;
    for (std::size_t k = begin; k < end; ++k) {
      if (!b.inlier[k]) continue;
      part.sum += b.moved[k];
      ++part.count;
    }
    b.centroid_blocks[block] = part;
  });
  Centroid total;
  for (std::size_t block = 0; block < block_count(n); ++block) {
    total.sum += b.centroid_blocks[block].sum;
    total.count += b.centroid_blocks[block].count;
  }
  sys.count = total.count;
  if (total.count == 0) return sys;
  const Vec3 c = total.sum / static_cast<double>(total.count);
  sys.centroid = c;
  sys.center = c;
  const double inv_l = 1.0 / length_scale;
  for_each_block(n, parallel, [&](std::size_t begin, std::size_t end, std::size_t block) {
    Moments part;
    for (std::size_t k = begin; k < end; ++k) {
      const double w = b.weight[k];
      if (!b.inlier[k] || w <= 0.0) continue;
      const Correspondence& m = b.matches[k];
      const Vec3 a = b.moved[k] - c;
      Vec6 J;
      J.head<3>() = a.cross(m.normal) * inv_l;
      J.tail<3>() = m.normal;
      const double r = b.residual[k];
      part.H.noalias() += (w * J) * J.transpose();
      part.g.noalias() += (w * r) * J;
      part.sum_w += w;
      part.sum_wr2 += w * r * r;
      if (curvature) {
        const double h = kernel_curvature(curvature_kernel, r, kernel_scale);
        part.H_curvature.noalias() += (h * J) * J.transpose();
        part.sum_curvature += h;
      }
      if (!point_moments) continue;
      const Vec3 fb = m.foot - c;
      part.sum_wa += w * a;
      part.sum_wb += w * fb;
      part.sum_wba.noalias() += (w * fb) * a.transpose();
    }
    b.moment_blocks[block] = part;
  });
  for (std::size_t block = 0; block < block_count(n); ++block)
    sys.m.add(b.moment_blocks[block]);
  decouple(sys);
  return sys;
}

// Eigenvectors of H_s whose eigenvalue is above threshold x the largest: the constrained
// subspace. Returns their count k; they are the last k columns of eigen.eigenvectors().
int constrained_count(const Eigen::SelfAdjointEigenSolver<Mat6>& eigen, double threshold) {
  const double largest = eigen.eigenvalues()(5);
  int k = 0;
  for (int i = 0; i < 6; ++i) {
    if (eigen.eigenvalues()(i) > threshold * largest) ++k;
  }
  return k;
}

// Step 6, solve. Point-to-plane: Gauss-Newton H_s xi_s = -g_s, solved in the constrained
// subspace only (truncated eigen pseudo-inverse), so the step has no component along free
// directions (Gelfand et al. 2003; Zhang, Kaess & Singh, "On degeneracy of optimization-based
// state estimation problems", ICRA 2016, who also project the update). Point-to-point: the
// weighted closed form of Umeyama (IEEE PAMI 1991; R = U S V^T from the SVD of the
// cross-covariance, S fixing a reflection) on pairs (q_i - c, f_i - c), converted
// to (omega, v) and projected onto the same subspace.
// When a curvature step is taken (IcpOptions::robust_newton): only near the optimum, where the
// robust objective is close to its quadratic model. There the IRLS step is a few standard
// deviations of the pose (the misalignment is far below the noise in every residual), and the
// curvature weights keep most of the IRLS weight (with Gaussian residuals, Tukey's keep 0.84:
// E[max(psi', 0)] / E[w]). Farther off, a curvature step overshoots and the iteration swings
// (an analytic scene from 5 degrees off took 15 iterations instead of 6): the step stays IRLS.
constexpr double kCurvatureWithinSigmas = 10.0;
constexpr double kCurvatureShare = 0.7;

// The step xi_s in standard deviations of the pose: sqrt(xi^T H xi / sigma^2), with sigma^2
// from the residuals the linear model predicts after the step, sum w (r + J xi)^2 =
// sum w r^2 + 2 g.xi + xi.H xi (before it, far from the solution, the residuals are mostly
// misalignment, not noise, and would make the step look small).
double step_sigmas(const LinearSystem& sys, const Vec6& xi_s, double* sigma2 = nullptr);

Step solve(IcpMethod method, const LinearSystem& sys, double threshold) {
  Step step;
  const double L = sys.length_scale;
  const Eigen::SelfAdjointEigenSolver<Mat6> eigen(sys.m.H);
  if (eigen.info() != Eigen::Success || !(eigen.eigenvalues()(5) > 0.0)) {
    step.finite = false;
    return step;
  }
  const int k = constrained_count(eigen, threshold);
  Vec6 xi_s;
  if (method == IcpMethod::point_to_plane) {
    xi_s.setZero();
    for (int i = 6 - k; i < 6; ++i) {
      const Vec6 u = eigen.eigenvectors().col(i);
      xi_s -= (u.dot(sys.m.g) / eigen.eigenvalues()(i)) * u;
    }
    // IcpOptions::robust_newton: the same gradient, the curvature's Hessian, in the same
    // constrained subspace U (the IRLS H's): (U^T H_c U) y = -U^T g, xi = U y. Kept only when
    // that reduced Hessian is positive definite.
    if (k > 0 && sys.m.sum_curvature >= kCurvatureShare * sys.m.sum_w &&
        step_sigmas(sys, xi_s) <= kCurvatureWithinSigmas) {
      // At most 6 x 6: on the stack, no allocation per iteration.
      using Reduced = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;
      using ReducedVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1>;
      const Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6> U = eigen.eigenvectors().rightCols(k);
      const Reduced reduced = U.transpose() * sys.m.H_curvature * U;
      const Eigen::LLT<Reduced> llt(reduced);
      if (llt.info() == Eigen::Success) {
        const ReducedVector y = llt.solve(-(U.transpose() * sys.m.g));
        if (y.allFinite()) xi_s = U * y;
      }
    }
  } else {
    const double W = sys.m.sum_w;
    const Vec3 mean_a = sys.m.sum_wa / W;
    const Vec3 mean_b = sys.m.sum_wb / W;
    // Cross-covariance sum w (b - mean_b)(a - mean_a)^T from moments about c.
    const Matrix3d M = sys.m.sum_wba - W * mean_b * mean_a.transpose();
    const Eigen::JacobiSVD<Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Matrix3d S = Matrix3d::Identity();
    if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0) S(2, 2) = -1.0;
    // a -> R a + t about c, i.e. the (omega, v) = (log R, t) of the update in step 7.
    const Matrix3d R = svd.matrixU() * S * svd.matrixV().transpose();
    // About the update centre c' = c + d: t' = t + (R - I) d.
    const Vec3 d = sys.center - sys.centroid;
    xi_s << L * log_so3(R), mean_b - R * mean_a + (R - Matrix3d::Identity()) * d;
    Vec6 projected = Vec6::Zero();
    for (int i = 6 - k; i < 6; ++i) {
      const Vec6 u = eigen.eigenvectors().col(i);
      projected += u.dot(xi_s) * u;
    }
    xi_s = projected;
  }
  step.xi << xi_s.head<3>() / L, xi_s.tail<3>();
  step.finite = step.xi.allFinite();
  step.scaled_norm = xi_s.norm();
  // Cov_s^-1 = H_s / sigma^2 on the constrained subspace, where xi_s lies.
  step.sigmas = step_sigmas(sys, xi_s, &step.sigma2);
  return step;
}

double step_sigmas(const LinearSystem& sys, const Vec6& xi_s, double* sigma2) {
  const double length2 = xi_s.dot(sys.m.H * xi_s);
  const double s2 = residual_variance(sys, sys.m.sum_wr2 + 2.0 * sys.m.g.dot(xi_s) + length2);
  if (sigma2 != nullptr) *sigma2 = s2;
  return s2 > 0.0        ? std::sqrt(std::max(0.0, length2) / s2)
         : length2 > 0.0 ? std::numeric_limits<double>::infinity()
                         : 0.0;
}

// Step 7, update: q -> c' + exp(omega) (q - c') + v, i.e. T <- Tr(c' + v) R(omega) Tr(-c') T.
// To first order this is the linearised motion q + omega x (q - c') + v of step 5. Rotation
// about c and translation are kept apart on purpose (an SO(3) x R^3 update rather than the
// SE(3) exponential, whose V(omega) v term would turn a translation along a constrained
// normal into a drift along a free in-plane direction); rotation re-orthonormalised.
Isometry3d update_pose(const Isometry3d& T, const Step& step, const Vec3& c) {
  Isometry3d about_c = Isometry3d::Identity();
  about_c.linear() = exp_so3(step.xi.head<3>());
  about_c.translation() = c + step.xi.tail<3>() - about_c.linear() * c;
  Isometry3d next = about_c * T;
  next.linear() = orthonormalize(next.linear());
  return next;
}

// Step 8, check convergence: increment small (rotation and centroid translation, or in
// standard deviations of the stage's pose estimate), or the inlier RMS no longer changing
// (relative to its previous value).
struct Tolerances {
  double rotation = 0.0;
  double translation = 0.0;
  double sigmas = 0.0;  // statistical; 0: off
};

bool step_is_small(const Tolerances& tol, double rotation, double translation, double sigmas) {
  return (rotation <= tol.rotation && translation <= tol.translation) ||
         (tol.sigmas > 0.0 && sigmas <= tol.sigmas);
}

bool has_converged(const IcpOptions& o, const Tolerances& tol, const IcpIteration& it,
                   double previous_rms) {
  if (step_is_small(tol, it.rotation_step, it.translation_step, it.step_sigmas)) return true;
  return std::isfinite(previous_rms) &&
         std::abs(it.rms - previous_rms) <= o.relative_rms_tolerance * previous_rms;
}

// A kept correspondence's residual |r| is its distance d up to rounding (an orthogonal foot, or
// one on a free edge along its normal within 1e-6: reject_boundary drops the others; see
// IcpOptions::kernel_bounded_search for the exception): a pass searched to `bound` keeps the
// points that weigh when the cut-off stays below this share of it.
constexpr double kSearchSlack = 1.0 - 1e-6;

// IcpOptions::kernel_bounded_search: how far this pass searches. Twice the previous pass's
// cut-off, plus twice the motion the last step gave the points: the scale of this pass, on
// residuals each moved by about that much, stays well inside (and the caller checks it did).
// The first pass (no scale yet), and the last stage's later passes, whose answers are the
// result's, search to max_correspondence_distance.
double search_bound(const IcpOptions& o, double previous_scale, double expected_motion,
                    bool result_pass) {
  const double full = o.max_correspondence_distance;
  if (!o.kernel_bounded_search || o.kernel != RobustKernel::tukey || o.keep_fraction < 1.0 ||
      !o.reject_boundary || result_pass || !(previous_scale > 0.0) ||
      !std::isfinite(expected_motion)) {
    return full;
  }
  const double kernel = o.kernel_scale > 0.0 ? o.kernel_scale : previous_scale;
  return std::min(full, 2.0 * tukey_cutoff(kernel) + 2.0 * expected_motion);
}

// Predicted convergence (IcpOptions::predict_convergence): near the solution ICP contracts
// linearly, xi_k+1 ~ rho xi_k, so with a clearly contracting observed rate the step after this
// one is ~rho times this one. If that predicted step would pass the tests, the iteration that
// would compute it (one more correspondence pass) is skipped.
bool predicted_converged(const Tolerances& tol, double rate, const IcpIteration& it) {
  if (!(rate <= 0.5)) return false;  // NaN (no rate yet) or not clearly contracting
  return step_is_small(tol, rate * it.rotation_step, rate * it.translation_step,
                       rate * it.step_sigmas);
}

// CorrespondenceQuery::later_queries on the last stage (all points): how many passes after this
// one the statistical test is expected to need, from this stage's own contraction: the step of
// this pass predicted as the last one times the rate of the last two. Only from a stage's third
// pass on: its first step is the previous stage's error, not a contraction, and how fast the
// steps then shrink depends on the part (linkrods about 0.04 a pass, the IEA blade and NIST
// CTC-02 0.3 to 0.5 at 0.5% noise; a rate carried over from the subsample stages forecast six
// passes on linkrods where two followed). Without a statistical tolerance the absolute ones
// decide: many passes. Subsample stages: 0 (not asked).
int later_queries(const IcpOptions& o, const Tolerances& tol, bool last_stage, int iteration,
                  double rate, double previous_step_sigmas) {
  constexpr int kMost = 8;
  if (!last_stage || iteration < 2) return 0;
  const int left = std::min(kMost, o.max_iterations - iteration - 1);
  if (left <= 0) return 0;
  if (!(tol.sigmas > 0.0)) return left;
  if (!(rate > 0.0 && rate < 1.0)) return 0;
  double step = rate * previous_step_sigmas;  // this pass's, predicted
  int later = 0;
  while (later < left && step > tol.sigmas) {
    ++later;
    step *= rate;
  }
  return later;
}

// RMS radius of the scan about its centroid (block-deterministic).
double scan_length_scale(std::span<const Vec3> scan, bool parallel) {
  const std::size_t n = scan.size();
  std::vector<Vec3> sums(block_count(n), Vec3::Zero());
  for_each_block(n, parallel, [&](std::size_t begin, std::size_t end, std::size_t block) {
    Vec3 s = Vec3::Zero();
    for (std::size_t k = begin; k < end; ++k)
      s += scan[k];
    sums[block] = s;
  });
  Vec3 total = Vec3::Zero();
  for (const Vec3& s : sums)
    total += s;
  const Vec3 centroid = total / static_cast<double>(n);
  std::vector<double> squares(block_count(n), 0.0);
  for_each_block(n, parallel, [&](std::size_t begin, std::size_t end, std::size_t block) {
    double s = 0.0;
    for (std::size_t k = begin; k < end; ++k)
      s += (scan[k] - centroid).squaredNorm();
    squares[block] = s;
  });
  double sum = 0.0;
  for (double s : squares)
    sum += s;
  return std::sqrt(sum / static_cast<double>(n));
}

// RMS radius about their centroid of the scan's points inside `box` (serial: a rare case).
double length_scale_within(std::span<const Vec3> scan, const engine::Aabb& box) {
  Vec3 sum = Vec3::Zero();
  std::size_t count = 0;
  for (const Vec3& p : scan) {
    if (box.squared_distance(p) > 0.0) continue;
    sum += p;
    ++count;
  }
  if (count == 0) return 0.0;
  const Vec3 centroid = sum / static_cast<double>(count);
  double squares = 0.0;
  for (const Vec3& p : scan) {
    if (box.squared_distance(p) == 0.0) squares += (p - centroid).squaredNorm();
  }
  return std::sqrt(squares / static_cast<double>(count));
}

// sigma^2 H_s^+ (sigma^2 from residual_variance) mapped to the unscaled twist about the model
// origin: xi = D^-1 xi_s with D = diag(L I, I), then v_origin = v_c + c x omega (adjoint of Tr(c)).
Mat6 pose_covariance(const LinearSystem& sys, double sigma2, double threshold) {
  if (sys.count <= 6 || !(sys.m.sum_w > 0.0)) return Mat6::Zero();
  const Eigen::SelfAdjointEigenSolver<Mat6> eigen(sys.m.H);
  if (!(eigen.eigenvalues()(5) > 0.0)) return Mat6::Zero();
  const int k = constrained_count(eigen, threshold);
  Mat6 cov_s = Mat6::Zero();
  for (int i = 6 - k; i < 6; ++i) {
    const Vec6 u = eigen.eigenvectors().col(i);
    cov_s += (sigma2 / eigen.eigenvalues()(i)) * u * u.transpose();
  }
  Mat6 D_inv = Mat6::Identity();
  D_inv.topLeftCorner<3, 3>() /= sys.length_scale;
  Mat6 A = Mat6::Identity();
  A.bottomLeftCorner<3, 3>() = skew(sys.center);
  const Mat6 AD = A * D_inv;
  return AD * cov_s * AD.transpose();
}

}  // namespace

IcpSolver::IcpSolver(IcpOptions options)
    : options_(std::move(options)), buffers_(std::make_unique<detail::IcpBuffers>()) {}
IcpSolver::~IcpSolver() = default;
IcpSolver::IcpSolver(IcpSolver&&) noexcept = default;
IcpSolver& IcpSolver::operator=(IcpSolver&&) noexcept = default;

IcpResult IcpSolver::align(CorrespondenceFinder& finder, std::span<const Vec3> scan,
                           const Isometry3d& T_model_scan_init) {
  const auto start = Clock::now();
  const IcpOptions& o = options_;
  Buffers& b = *buffers_;
  IcpResult result;
  result.T_model_scan = T_model_scan_init;
  result.points = scan.size();
  const auto finish = [&](IcpTermination termination, std::string message) {
    result.termination = termination;
    result.message = std::move(message);
    result.seconds = seconds_since(start);
    return result;
  };

  if (auto e = o.validate()) return finish(IcpTermination::invalid_input, "options: " + *e);
  if (!T_model_scan_init.matrix().allFinite()) {
    return finish(IcpTermination::invalid_input, "initial pose: non-finite entries");
  }
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (!scan[i].allFinite()) {
      return finish(IcpTermination::invalid_input,
                    "scan point " + std::to_string(i) + ": non-finite coordinate");
    }
  }
  if (scan.size() < o.min_correspondences) {
    return finish(IcpTermination::too_few_correspondences,
                  "scan has " + std::to_string(scan.size()) +
                      " points, fewer than min_correspondences (" +
                      std::to_string(o.min_correspondences) + ")");
  }
  double L = scan_length_scale(scan, o.parallel);
  // A few stray points far from the rest (a scanner's glitch at 1e14) would make L their
  // distance, and with it the translation tolerance, the scaled step and the degeneracy test
  // (the bearing with one point at 1e14: three iterations, "free" in every rotation, 0.018
  // degrees off). An RMS radius beyond the diagonal of the box that holds all but the extreme
  // 0.1% can only come from such points: L is then the radius of the points in that box. A scan
  // without them keeps its L to the bit.
  const engine::Aabb bulk = engine::trimmed_box(engine::PointView::of(scan));
  if (L > bulk.diagonal()) L = length_scale_within(scan, bulk);
  if (!(L > 0.0)) return finish(IcpTermination::invalid_input, "scan: all points coincide");
  const double translation_tolerance =
      o.translation_tolerance > 0.0 ? o.translation_tolerance : 1e-10 * L;

  finder.reset(scan.size());
  std::vector<std::size_t> stage_sizes = coarse_schedule(o, scan.size());
  stage_sizes.push_back(scan.size());

  Isometry3d T = T_model_scan_init;
  IcpTermination termination = IcpTermination::max_iterations;
  std::string message;
  // The system of the last completed iteration on all points (its correspondences are the
  // finder's last answer): the result's statistics, with no extra projection pass.
  std::optional<LinearSystem> final_system;
  bool final_at_pose = false;  // final_system was found at T (its step not applied)
  Rejection final_kept;
  double final_sigma2 = 0.0;
  // IcpOptions::robust_newton, on all points only: a subsample stage ends on a predicted step
  // (predict_convergence), which a full curvature step would make one iteration later.
  const bool curvature_steps = o.robust_newton && o.method == IcpMethod::point_to_plane;
  // Latest observed contraction rate of successive steps (|xi_s| ratio), for prediction.
  double rate = std::numeric_limits<double>::quiet_NaN();
  // The last step's displacement of the points (CorrespondenceQuery::expected_motion).
  double expected_motion = o.initial_expected_motion;
  // The kernel scale of the previous pass (0: none yet), for IcpOptions::kernel_bounded_search.
  double previous_scale = 0.0;
  for (std::size_t stage = 0; stage < stage_sizes.size(); ++stage) {
    const bool last_stage = stage + 1 == stage_sizes.size();
    const Tolerances tol{o.rotation_tolerance, translation_tolerance,
                         last_stage ? o.statistical_tolerance : o.coarse_statistical_tolerance};
    // One seed for all stages: nested subsamples (select_points).
    select_points(scan.size(), stage_sizes[stage], o.subsample_seed, b.ids);
    b.resize(b.ids.size());
    termination = IcpTermination::max_iterations;
    message = "no convergence within max_iterations (" + std::to_string(o.max_iterations) + ")";
    double previous_rms = std::numeric_limits<double>::quiet_NaN();
    double previous_step = std::numeric_limits<double>::quiet_NaN();
    double previous_step_sigmas = std::numeric_limits<double>::quiet_NaN();
    for (int iteration = 0; iteration < o.max_iterations; ++iteration) {
      const auto t0 = Clock::now();
      if (t0 >= o.deadline) {
        termination = IcpTermination::time_limit;
        message = "time limit exceeded after " + std::to_string(result.iterations) + " iterations";
        break;
      }
      final_system.reset();
      final_at_pose = false;
      transform_points(T, scan, b, o.parallel);
      // Steps 2-4 with correspondences searched to `bound`: the kernel's scale.
      const int later = later_queries(o, tol, last_stage, iteration, rate, previous_step_sigmas);
      const auto correspond = [&](double bound) {
        find_correspondences(finder, bound, o.parallel, expected_motion, later, b);
        reject_outliers(o, b);
        return compute_weights(o, L, b);
      };
      const double bound =
          search_bound(o, previous_scale, expected_motion, last_stage && iteration > 0);
      IcpIteration it;
      it.kernel_scale = correspond(bound);
      if (bound < o.max_correspondence_distance &&
          !(tukey_cutoff(it.kernel_scale) < kSearchSlack * bound)) {
        // The cut-off came out beyond the bound (the scale grew): points that would weigh may
        // have been left out. This pass again, searched to max_correspondence_distance.
        spdlog::debug(
            "icp: kernel cut-off {:.3g} beyond the search bound {:.3g}: searched again in full",
            tukey_cutoff(it.kernel_scale), bound);
        it.kernel_scale = correspond(o.max_correspondence_distance);
      }
      previous_scale = it.kernel_scale;
      const Rejection kept = inlier_statistics(b);
      it.stage = static_cast<int>(stage);
      it.points = b.ids.size();
      it.inliers = kept.inliers;
      it.rms = kept.rms;
      if (kept.inliers < o.min_correspondences) {
        termination = IcpTermination::too_few_correspondences;
        message = std::to_string(kept.inliers) + " inliers of " + std::to_string(b.ids.size()) +
                  " points, fewer than min_correspondences (" +
                  std::to_string(o.min_correspondences) + "); rejected: " + rejection_summary(o, b);
        break;
      }
      const LinearSystem sys =
          linearize(L, o.parallel, o.method == IcpMethod::point_to_point, b,
                    curvature_steps && last_stage ? o.kernel : RobustKernel::none, it.kernel_scale);
      const Step step = solve(o.method, sys, o.degeneracy_threshold);
      if (!step.finite) {
        termination = IcpTermination::numerical_failure;
        message = "non-finite or empty normal equations";
        break;
      }
      if (last_stage) {
        final_system = sys;
        final_kept = kept;
      }
      it.rotation_step = step.xi.head<3>().norm();
      it.translation_step = step.xi.tail<3>().norm();
      // How far this step moved the points (those within about 2 L of the centre), as the
      // finder's guess for the next move: steps shrink as ICP converges.
      expected_motion = 2.0 * L * it.rotation_step + it.translation_step;
      it.step_sigmas = step.sigmas;
      previous_step_sigmas = step.sigmas;
      if (previous_step > 0.0) rate = step.scaled_norm / previous_step;
      previous_step = step.scaled_norm;
      const bool converged = has_converged(o, tol, it, previous_rms);
      const bool predict = last_stage ? o.predict_final_convergence : o.predict_convergence;
      it.predicted = !converged && predict && predicted_converged(tol, rate, it);
      // Converged on all points: the pose whose correspondences were just found is the result
      // (the step computed there is below tolerance), so the statistics above describe it
      // exactly and the finder's answers are its projections. Applying the step would move the
      // pose by less than the tolerance and leave it without them (one more pass to evaluate).
      // A coarse stage's step is applied (the next stage evaluates it anyway).
      it.applied = !(last_stage && converged);
      if (it.applied) {
        T = update_pose(T, step, sys.center);
        final_sigma2 = step.sigma2;
      } else {
        final_at_pose = true;
        final_sigma2 = residual_variance(sys, sys.m.sum_wr2);
      }
      it.seconds = seconds_since(t0);
      result.log.push_back(it);
      ++result.iterations;
      if (o.on_iteration) o.on_iteration(it);
      spdlog::debug(
          "icp stage {} iteration {}: rms {:.6g}, inliers {}/{}, step {:.3g} rad {:.3g} "
          "({:.3g} sigma){}",
          stage, iteration, it.rms, it.inliers, it.points, it.rotation_step, it.translation_step,
          it.step_sigmas, it.predicted ? ", next step predicted below tolerance" : "");
      if (converged || it.predicted) {
        termination = IcpTermination::converged;
        message = converged ? "increment or RMS change below tolerance"
                            : "next increment predicted below tolerance";
        break;
      }
      previous_rms = it.rms;
    }
    if (termination == IcpTermination::too_few_correspondences ||
        termination == IcpTermination::numerical_failure ||
        termination == IcpTermination::time_limit) {
      break;
    }
  }
  result.T_model_scan = T;

  // After max_iterations the last step was applied: evaluate the returned pose (below), as
  // the caller would have to anyway. A predicted convergence (predict_final_convergence) or a
  // time limit keeps the statistics of the pose before the last step, and says so
  // (IcpResult::statistics_at_pose).
  if (final_system && !final_at_pose && termination == IcpTermination::max_iterations) {
    final_system.reset();
  }
  if (final_system) {
    result.statistics_at_pose = final_at_pose;
    result.inliers = final_kept.inliers;
    result.rms = final_kept.rms;
    if (final_system->m.sum_w > 0.0 && final_system->m.H.allFinite()) {
      result.covariance = pose_covariance(*final_system, final_sigma2, o.degeneracy_threshold);
      result.degeneracy =
          analyse_degeneracy(final_system->m.H, final_system->center, L, o.degeneracy_threshold);
    }
  } else {
    // No completed full-resolution step at the returned pose (a failure, or the last stage ran
    // out of iterations): evaluate there on all points, so that the statistics describe it.
    result.statistics_at_pose = true;
    select_points(scan.size(), scan.size(), 0, b.ids);
    b.resize(b.ids.size());
    transform_points(T, scan, b, o.parallel);
    find_correspondences(finder, o.max_correspondence_distance, o.parallel, expected_motion, 0, b);
    reject_outliers(o, b);
    compute_weights(o, L, b);
    const Rejection kept = inlier_statistics(b);
    result.inliers = kept.inliers;
    result.rms = kept.rms;
    if (kept.inliers > 0) {
      const LinearSystem sys = linearize(L, o.parallel, o.method == IcpMethod::point_to_point, b);
      if (sys.m.sum_w > 0.0 && sys.m.H.allFinite()) {
        result.covariance =
            pose_covariance(sys, residual_variance(sys, sys.m.sum_wr2), o.degeneracy_threshold);
        result.degeneracy = analyse_degeneracy(sys.m.H, sys.center, L, o.degeneracy_threshold);
      }
    }
  }
  if (termination == IcpTermination::converged && result.degeneracy.degenerate()) {
    termination = IcpTermination::degenerate;
    message = "converged in the constrained directions only; free: " + result.degeneracy.describe();
  }
  return finish(termination, message);
}

std::vector<std::size_t> coarse_schedule(const IcpOptions& options, std::size_t n) {
  std::vector<std::size_t> sizes;
  if (!options.coarse_sizes.empty()) {
    for (std::size_t m : options.coarse_sizes) {
      if (m < n) sizes.push_back(m);
    }
    return sizes;
  }
  if (!options.auto_coarse) return sizes;
  for (std::size_t m : {n / 100, n / 10}) {
    if (m >= kAutoCoarseMinPoints) sizes.push_back(m);
  }
  return sizes;
}

IcpResult align(CorrespondenceFinder& finder, std::span<const Vec3> scan,
                const Isometry3d& T_model_scan_init, const IcpOptions& options) {
  IcpSolver solver(options);
  return solver.align(finder, scan, T_model_scan_init);
}

}  // namespace nurbsreg::icp
