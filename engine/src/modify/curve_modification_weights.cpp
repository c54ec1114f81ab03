// Weight changes of seed paper 004: eqs. 8-13, Process 1 and the local form (eqs. 16-19).
//
// Re-derivation of eqs. 8-13. With dB = 0, eq. (2) reads (eq. 8)
//     sum_i N_i(t_j) dW_i (B_i - P_j) = S_j (P_j - C_j).
// Projecting on u_j = (B_nose - P_j)/|B_nose - P_j| gives the scalar eq. 10,
//     sum_i dW_i J_{j,i} = S_j u_j·(P_j - C_j),   J_{j,i} = N_i(t_j) u_j·(B_i - P_j),
// one row per segment; with the end weights fixed these rows form eq. 13 (square and
// tridiagonal for degree 2 with simple knots). The printed eq. 13 matrix mixes in b_{2,4}: a typo
// for J_{2,4}.
//
// Process 1, re-derived. Adding the identity sum_i W_i J_{j,i} = S_j u_j·(C_j - P_j) to eq. 10
// shows that the *new* weights W' = W + dW satisfy the homogeneous rows
//     sum_i W'_i J_{j,i} = 0   for every segment j             (this is eq. 14's content),
// so the admissible new weight vectors form the null space of the n x (n + degree) matrix J over
// all control points (end weights included): dimension 2 for degree 2 with simple knots. Eq. 13
// picks the member with unchanged end weights. The paper's Process 1 (whose printed loops are
// garbled) picks another member: for a control point i whose new weight is not positive it sets
// dW'_i = -dW_i (restoring W_i), splits the balancing term of the row whose nose control point is
// i between its neighbours with A + B = 1, and propagates outwards through the other rows, which
// is the same as solving for the null-space vector with those two prescribed entries. We do
// exactly that (via an orthonormal null-space basis, which avoids dividing by small J entries
// during the propagation), try A in [0, 1] starting at 1/2, and keep the first A that makes every
// weight positive (the paper only checks the two neighbours). When that fails and the null space
// is two-dimensional, the positive cone is found exactly: each weight W'_k = n_k·c > 0 is a half
// plane of directions c, and their intersection is an arc; we take its mid-direction.

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "modify/curve_modification_detail.hpp"

namespace nurbsreg::engine {

namespace {

// The eq. 10 rows over all control points, and eq. 13's solution.
struct WeightSystem {
  Eigen::MatrixXd j_full;   // n x count: J_{j,i}
  Eigen::VectorXd rhs;      // S_j u_j·(P_j - C_j)
  std::vector<Vec3> u_dir;  // u_j
  Eigen::VectorXd delta;    // eq. 13: dW (count entries, end entries 0)
  double residual = 0.0;
  int rank = 0;
};

double curve_scale(const NurbsCurve& curve) {
  double s = 0.0;
  for (const Vec3& b : curve.control_points)
    s = std::max(s, b.norm());
  return std::max(s, 1.0);
}

// u_j: the unit vector from P_j to the nose control point. When the target sits on that control
// point the direction is undefined; any direction works for the row then (the right-hand side and
// the nose term vanish), so fall back to the displacement or to the nose-to-control direction.
Vec3 u_direction(const NurbsCurve& curve, const NosePoint& nose, const Vec3& target) {
  const double eps = 1e-12 * curve_scale(curve);
  const Vec3 candidates[3] = {curve.control_points[nose.nose_control] - target, target - nose.point,
                              curve.control_points[nose.nose_control] - nose.point};
  for (const Vec3& c : candidates) {
    if (c.norm() > eps) return c.normalized();
  }
  return Vec3::UnitX();
}

WeightSystem weight_system(const NurbsCurve& curve, std::span<const NosePoint> noses,
                           std::span<const Vec3> targets) {
  const int count = curve.count();
  const int n = static_cast<int>(noses.size());
  WeightSystem sys;
  sys.j_full = Eigen::MatrixXd::Zero(n, count);
  sys.rhs = Eigen::VectorXd::Zero(n);
  for (int j = 0; j < n; ++j) {
    const detail::BasisRow row = detail::basis_row(curve, noses[j]);
    const Vec3 u = u_direction(curve, noses[j], targets[j]);
    sys.u_dir.push_back(u);
    for (int k = 0; k <= curve.degree; ++k) {
      const int i = row.first + k;
      sys.j_full(j, i) = row.values[k] * u.dot(curve.control_points[i] - targets[j]);
    }
    sys.rhs(j) = row.weight_sum * u.dot(targets[j] - curve.evaluate(noses[j].u));
  }
  sys.delta = Eigen::VectorXd::Zero(count);
  if (count > 2 && n > 0) {
    const detail::LinearSolution sol =
        detail::solve_linear(sys.j_full.middleCols(1, count - 2), sys.rhs);
    sys.delta.segment(1, count - 2) = sol.x.col(0);
    sys.residual = sol.residual;
    sys.rank = sol.rank;
  }
  return sys;
}

bool all_above(const Eigen::VectorXd& w, double ratio) {
  const double floor = ratio * w.maxCoeff();
  return w.maxCoeff() > 0.0 && (w.array() > floor).all();
}

// Orthonormal basis of the null space of J (count x d).
Eigen::MatrixXd null_space(const Eigen::MatrixXd& j_full) {
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(j_full, Eigen::ComputeFullV);
  svd.setThreshold(1e-12);
  const int rank = static_cast<int>(svd.rank());
  return svd.matrixV().rightCols(j_full.cols() - rank);
}

// The positive cone of a two-dimensional null space (see the file comment): the direction in the
// middle of the feasible arc, or nothing if the half planes have no common interior.
std::optional<Eigen::VectorXd> positive_member_2d(const Eigen::MatrixXd& basis, double ratio) {
  const int count = static_cast<int>(basis.rows());
  std::vector<double> phi(count);
  for (int k = 0; k < count; ++k) {
    if (basis.row(k).norm() < 1e-14) return std::nullopt;  // weight k is 0 in every member
    phi[k] = std::atan2(basis(k, 1), basis(k, 0));
  }
  double lo = -std::numbers::pi;
  double hi = std::numbers::pi;
  double rel_max = -std::numbers::pi;
  double rel_min = std::numbers::pi;
  for (int k = 0; k < count; ++k) {
    double rel = std::remainder(phi[k] - phi[0], 2.0 * std::numbers::pi);
    rel_max = std::max(rel_max, rel);
    rel_min = std::min(rel_min, rel);
  }
  lo = rel_max - 0.5 * std::numbers::pi;
  hi = rel_min + 0.5 * std::numbers::pi;
  if (!(lo < hi)) return std::nullopt;
  const double theta = phi[0] + 0.5 * (lo + hi);
  Eigen::VectorXd w = basis * Eigen::Vector2d(std::cos(theta), std::sin(theta));
  if (!all_above(w, ratio)) return std::nullopt;
  return w;
}

}  // namespace

StepResult change_weights(const NurbsCurve& curve, std::span<const NosePoint> noses,
                          std::span<const Vec3> targets, const WeightOptions& options) {
  detail::check_inputs(curve, noses, targets);
  StepResult out;
  out.curve = detail::with_explicit_weights(curve);
  const int count = curve.count();
  out.delta_points.assign(count, Vec3::Zero());
  out.delta_weights.assign(count, 0.0);
  if (count <= 2 || noses.empty()) {
    out.applicable = false;
    out.message = "no free weights (the end weights are fixed)";
    return out;
  }
  const WeightSystem sys = weight_system(curve, noses, targets);
  Eigen::VectorXd w0(count);
  for (int i = 0; i < count; ++i)
    w0(i) = curve.weight(i);
  out.delta_weights_eq13.assign(sys.delta.data(), sys.delta.data() + count);
  Eigen::VectorXd w = w0 + sys.delta;
  out.residual = sys.residual;
  out.exact = sys.residual <= detail::kExactResidual;
  out.message = "eq. 13: rank " + std::to_string(sys.rank) + " of " + std::to_string(count - 2) +
                " free weights";

  if (!all_above(w, options.min_weight_ratio)) {
    if (!options.process1) {
      out.applicable = false;
      out.curve = detail::with_explicit_weights(curve);
      out.message += "; a new weight is not positive and Process 1 is disabled";
      return out;
    }
    const Eigen::MatrixXd basis = null_space(sys.j_full);
    const int dim = static_cast<int>(basis.cols());
    std::string how = "none";
    for (int i = 1; i + 1 < count && dim > 0; ++i) {
      if (w(i) > options.min_weight_ratio * w.maxCoeff()) continue;
      const double restore = w0(i) - w(i);  // dW'_i = -dW_i: back to the original weight
      // The segment whose nose control point is i, if any (the row that Process 1 balances).
      int row = -1;
      for (std::size_t j = 0; j < noses.size(); ++j) {
        if (noses[j].nose_control == i) row = static_cast<int>(j);
      }
      std::optional<Eigen::VectorXd> accepted;
      std::optional<Eigen::VectorXd> neighbours_ok;
      if (curve.degree == 2 && dim == 2 && row >= 0 && sys.j_full(row, i + 1) != 0.0 &&
          sys.j_full(row, i - 1) != 0.0) {
        // A = 1/2, then alternately below and above it, down to 0 and up to 1.
        for (int step = 0; step <= 20 && !accepted; ++step) {
          const double a = 0.5 + ((step % 2 == 0) ? 1.0 : -1.0) * 0.05 * ((step + 1) / 2);
          const double next = -a * sys.j_full(row, i) * restore / sys.j_full(row, i + 1);
          Eigen::Matrix2d m;
          m << basis(i, 0), basis(i, 1), basis(i + 1, 0), basis(i + 1, 1);
          Eigen::FullPivLU<Eigen::Matrix2d> lu(m);
          if (!lu.isInvertible()) break;
          const Eigen::Vector2d c = lu.solve(Eigen::Vector2d(restore, next));
          const Eigen::VectorXd candidate = w + basis * c;
          if (all_above(candidate, options.min_weight_ratio)) {
            accepted = candidate;
          } else if (!neighbours_ok && candidate(i - 1) > 0.0 && candidate(i + 1) > 0.0) {
            neighbours_ok = candidate;
          }
        }
        how = "Process 1 (A/B split)";
      } else {
        // Other degrees: the minimum-norm null-space correction that restores W_i.
        const Eigen::RowVectorXd r = basis.row(i);
        if (r.squaredNorm() > 0.0) {
          accepted = Eigen::VectorXd(w + basis * (r.transpose() * (restore / r.squaredNorm())));
        }
        how = "Process 1 (minimum-norm allocation)";
      }
      if (accepted) {
        w = *accepted;
      } else if (neighbours_ok) {
        w = *neighbours_ok;
      }
    }
    if (!all_above(w, options.min_weight_ratio) && dim == 2) {
      if (auto positive = positive_member_2d(basis, options.min_weight_ratio)) {
        w = *positive;
        how = "positive cone of the eq. 14 null space";
      }
    }
    if (!all_above(w, options.min_weight_ratio)) {
      out.applicable = false;
      out.curve = detail::with_explicit_weights(curve);
      out.message += "; no positive weights satisfy eq. 10 for every segment";
      return out;
    }
    // The curve does not change when all weights are scaled; keep the first weight as given.
    w *= w0(0) / w(0);
    out.message += "; " + how + " applied (end weights may change)";
    out.exact = (sys.j_full * w).norm() <= detail::kExactResidual * sys.j_full.norm() * w.norm();
  }
  for (int i = 0; i < count; ++i) {
    out.delta_weights[i] = w(i) - w0(i);
    out.curve.weights[i] = w(i);
  }
  return out;
}

// Eqs. 16-19, re-derived. For segment s with outer control points a, b and nose control point m,
// eq. 8 splits into the u_s component (eq. 10) and the component perpendicular to u_s. B_m - P
// is parallel to u_s, so only a and b act sideways: the perpendicular forces balance (eq. 11)
// when N_a dW_a r_a + N_b dW_b r_b = 0 with r = (B - P) minus its u_s part, i.e. dW_b = d dW_a.
// Eq. 12/16 writes d with magnitudes (|(B - P) x u|), which presumes a and b on opposite sides;
// we use the signed least-squares ratio d = -(N_a r_a)·(N_b r_b) / |N_b r_b|^2, equal to eq. 16
// in that case and the best balance in 3-D. Eq. 17 keeps the u_s row's value:
// dW*_a J_a + dW*_b J_b = dW_a J_a + dW_b J_b, so dW*_a = (dW_a J_a + dW_b J_b)/(J_a + d J_b),
// dW*_b = d dW*_a (eq. 19) and dW*_m = dW_m (eq. 18).
StepResult change_weights_local(const NurbsCurve& curve, std::span<const NosePoint> noses,
                                std::span<const Vec3> targets, int segment) {
  detail::check_inputs(curve, noses, targets);
  if (segment < 0 || segment >= static_cast<int>(noses.size())) {
    throw std::invalid_argument("curve \"" + curve.name + "\": segment " + std::to_string(segment) +
                                " out of range");
  }
  StepResult out;
  out.curve = detail::with_explicit_weights(curve);
  const int count = curve.count();
  out.delta_points.assign(count, Vec3::Zero());
  out.delta_weights.assign(count, 0.0);
  if (curve.degree != 2 || count <= 2) {
    out.applicable = false;
    out.message = "the local weight form (eqs. 16-19) needs degree 2";
    return out;
  }
  // Only `segment` moves; the others are held at their nose points.
  std::vector<Vec3> local_targets(noses.size());
  for (std::size_t j = 0; j < noses.size(); ++j)
    local_targets[j] = noses[j].point;
  local_targets[segment] = targets[segment];
  const WeightSystem sys = weight_system(curve, noses, local_targets);
  out.delta_weights_eq13.assign(sys.delta.data(), sys.delta.data() + count);

  const NosePoint& nose = noses[segment];
  const detail::BasisRow row = detail::basis_row(curve, nose);
  const int a = row.first;
  const int b = row.first + 2;
  const Vec3& p = targets[segment];
  const Vec3& u = sys.u_dir[segment];
  auto perpendicular = [&](int i) {
    const Vec3 v = curve.control_points[i] - p;
    return Vec3(v - v.dot(u) * u);
  };
  const Vec3 force_a = row.values[0] * perpendicular(a);
  const Vec3 force_b = row.values[2] * perpendicular(b);
  const double ja = sys.j_full(segment, a);
  const double jb = sys.j_full(segment, b);
  if (force_b.squaredNorm() <= 1e-24 * curve_scale(curve)) {
    out.applicable = false;
    out.message = "eq. 16: the last governing control point lies on the line P B_nose";
    return out;
  }
  const double d = -force_a.dot(force_b) / force_b.squaredNorm();
  const double denominator = ja + d * jb;
  if (std::abs(denominator) <= 1e-14 * (std::abs(ja) + std::abs(d * jb))) {
    out.applicable = false;
    out.message = "eq. 17: J_a + d J_b vanishes";
    return out;
  }
  Eigen::VectorXd delta = sys.delta;
  delta(a) = (sys.delta(a) * ja + sys.delta(b) * jb) / denominator;
  delta(b) = d * delta(a);
  for (int i = 0; i < count; ++i) {
    const double w = curve.weight(i) + delta(i);
    if (!(w > 0.0)) {
      out.curve = detail::with_explicit_weights(curve);
      out.applicable = false;
      out.message = "eqs. 16-19 give weight " + std::to_string(i) + " <= 0";
      return out;
    }
    out.curve.weights[i] = w;
    out.delta_weights[i] = delta(i);
  }
  const double moved = (p - nose.point).norm();
  const double miss = (out.curve.evaluate(nose.u) - p).norm();
  out.residual = moved > 0.0 ? miss / moved : miss;
  out.exact = out.residual <= 1e-9;
  out.message = "eqs. 16-19: segment " + std::to_string(segment) + ", d = " + std::to_string(d);
  return out;
}

}  // namespace nurbsreg::engine
