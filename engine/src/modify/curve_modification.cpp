// Nose points, control-point movement (eqs. 3-7), joining-knot positioning (eqs. 20-21) and the
// shared helpers of seed paper 004 (Lu & Huang 1998).
//
// Eq. (2), re-derived (the extraction of the paper's intermediate steps is garbled). Write
// S = sum_i N_i W_i and C = sum_i N_i W_i B_i / S at t = t_pj. The modified curve passes through
// P_j at the same parameter iff
//     sum_i N_i (W_i + dW_i)(B_i + dB_i) = (S + sum_i N_i dW_i) P_j.
// Expanding the left side, sum_i N_i W_i B_i = S C, so
//     sum_i N_i (W_i + dW_i) dB_i + S C + sum_i N_i dW_i B_i = S P_j + sum_i N_i dW_i P_j,
// i.e. eq. (2):
//     sum_i N_i (W_i + dW_i) dB_i + sum_i N_i dW_i (B_i - P_j) = S (P_j - C).
// No linearisation is involved: eq. (2) is an exact equivalence. With dW = 0 it is linear in dB
// (eq. 3), so eqs. 5 and 7 put the nose points exactly on their targets; with dB = 0 it is
// linear in dW (eq. 8).

#include "nurbsreg/engine/curve_modification.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "geometry/basis.hpp"
#include "modify/curve_modification_detail.hpp"

namespace nurbsreg::engine {

namespace detail {

BasisRow basis_row(const NurbsCurve& curve, const NosePoint& nose) {
  BasisRow row;
  row.degree = curve.degree;
  row.first = nose.span - curve.degree;
  // The span is passed explicitly: at a span end (possible with the nearest-point rule) the
  // values are the limit from inside the segment, which is what the segment's equation needs.
  basis_functions(nose.span, nose.u, curve.degree, curve.knots, row.values);
  for (int k = 0; k <= curve.degree; ++k) {
    row.weight_sum += row.values[k] * curve.weight(row.first + k);
  }
  return row;
}

LinearSolution solve_linear(const Eigen::MatrixXd& a, const Eigen::MatrixXd& r) {
  LinearSolution out;
  bool solved = false;
  if (a.rows() == a.cols() && a.rows() > 0) {
    Eigen::FullPivLU<Eigen::MatrixXd> lu(a);
    if (lu.isInvertible()) {
      out.x = lu.solve(r);
      out.rank = static_cast<int>(a.rows());
      solved = true;
    }
  }
  if (!solved) {
    Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(a);
    out.x = cod.solve(r);
    out.rank = static_cast<int>(cod.rank());
  }
  const double scale = r.norm();
  out.residual = scale > 0.0 ? (a * out.x - r).norm() / scale : 0.0;
  return out;
}

NurbsCurve with_explicit_weights(const NurbsCurve& curve) {
  NurbsCurve out = curve;
  if (out.weights.empty()) out.weights.assign(curve.control_points.size(), 1.0);
  return out;
}

void check_inputs(const NurbsCurve& curve, std::span<const NosePoint> noses,
                  std::span<const Vec3> targets) {
  if (auto e = curve.validate()) {
    throw std::invalid_argument("curve \"" + curve.name + "\": " + *e);
  }
  if (noses.size() != targets.size()) {
    throw std::invalid_argument("curve \"" + curve.name + "\": " + std::to_string(targets.size()) +
                                " targets for " + std::to_string(noses.size()) + " nose points");
  }
  for (std::size_t j = 0; j < targets.size(); ++j) {
    if (!targets[j].allFinite()) {
      throw std::invalid_argument("curve \"" + curve.name + "\": target " + std::to_string(j) +
                                  " is not a finite point");
    }
  }
}

}  // namespace detail

std::vector<CurveSegment> curve_segments(const NurbsCurve& curve) {
  std::vector<CurveSegment> out;
  for (int s = curve.degree; s < curve.count(); ++s) {
    if (curve.knots[s] < curve.knots[s + 1])
      out.push_back({s, {curve.knots[s], curve.knots[s + 1]}});
  }
  return out;
}

int nose_control_index(const NurbsCurve& curve, int span) {
  return span - (curve.degree + 1) / 2;
}

namespace {

// Nearest point of the segment to q: 16 samples per degree bracket the smallest sampled squared
// distance, golden section narrows that bracket, Newton on (C - q)·C' = 0 polishes. This finds the
// global minimum whenever the samples resolve its basin (a single span of a low-degree curve has
// few local minima); it is checked against 200,000-sample brute force in the tests, and it is
// not an exact projection (that is the engine's curve projector's job).
double nearest_parameter(const NurbsCurve& curve, const ParamInterval& param, const Vec3& q) {
  const int samples = 16 * std::max(curve.degree, 1);
  auto dist2 = [&](double u) { return (curve.evaluate(u) - q).squaredNorm(); };
  int best = 0;
  double best_d = dist2(param.lo);
  for (int k = 1; k <= samples; ++k) {
    const double d = dist2(param.to_parent(static_cast<double>(k) / samples));
    if (d < best_d) {
      best_d = d;
      best = k;
    }
  }
  double a = param.to_parent(static_cast<double>(std::max(best - 1, 0)) / samples);
  double b = param.to_parent(static_cast<double>(std::min(best + 1, samples)) / samples);
  const double golden = 0.5 * (std::sqrt(5.0) - 1.0);
  double c = b - golden * (b - a);
  double d = a + golden * (b - a);
  double fc = dist2(c);
  double fd = dist2(d);
  for (int it = 0; it < 80 && b - a > 1e-14 * (param.width() + 1.0); ++it) {
    if (fc < fd) {
      b = d;
      d = c;
      fd = fc;
      c = b - golden * (b - a);
      fc = dist2(c);
    } else {
      a = c;
      c = d;
      fc = fd;
      d = a + golden * (b - a);
      fd = dist2(d);
    }
  }
  double u = 0.5 * (a + b);
  double fu = dist2(u);
  for (int it = 0; it < 5; ++it) {
    Vec3 der[3];
    curve.derivatives(u, 2, der);
    const double g = (der[0] - q).dot(der[1]);
    const double h = der[1].squaredNorm() + (der[0] - q).dot(der[2]);
    if (!(h > 0.0)) break;
    const double next = std::clamp(u - g / h, param.lo, param.hi);
    const double fn = dist2(next);
    if (!(fn < fu)) break;
    u = next;
    fu = fn;
  }
  // The end points are candidates too (the minimum may sit on a joining point).
  if (dist2(param.lo) < fu) u = param.lo;
  if (dist2(param.hi) < dist2(u)) u = param.hi;
  return u;
}

}  // namespace

std::vector<NosePoint> nose_points(const NurbsCurve& curve, NoseRule rule) {
  std::vector<NosePoint> out;
  const std::vector<CurveSegment> segments = curve_segments(curve);
  out.reserve(segments.size());
  for (std::size_t j = 0; j < segments.size(); ++j) {
    NosePoint nose;
    nose.segment = static_cast<int>(j);
    nose.span = segments[j].span;
    nose.nose_control = nose_control_index(curve, nose.span);
    if (rule == NoseRule::mean_parameter) {
      nose.u = 0.5 * (segments[j].param.lo + segments[j].param.hi);
    } else {
      nose.u = nearest_parameter(curve, segments[j].param, curve.control_points[nose.nose_control]);
    }
    nose.point = curve.evaluate(nose.u);
    out.push_back(nose);
  }
  return out;
}

std::vector<Vec3> joining_points(const NurbsCurve& curve) {
  std::vector<Vec3> out;
  const std::vector<CurveSegment> segments = curve_segments(curve);
  for (std::size_t j = 0; j + 1 < segments.size(); ++j) {
    out.push_back(curve.evaluate(segments[j].param.hi));
  }
  return out;
}

std::vector<double> nose_errors(std::span<const NosePoint> noses, std::span<const Vec3> targets) {
  std::vector<double> out(noses.size());
  for (std::size_t j = 0; j < noses.size(); ++j)
    out[j] = (targets[j] - noses[j].point).norm();
  return out;
}

double improvement_efficiency(std::span<const double> previous, std::span<const double> current) {
  double before = 0.0;
  double gain = 0.0;
  for (std::size_t j = 0; j < previous.size(); ++j) {
    before += previous[j];
    gain += previous[j] - current[j];
  }
  return before > 0.0 ? gain / before : 0.0;
}

StepResult move_nose_control_point(const NurbsCurve& curve, const NosePoint& nose,
                                   const Vec3& target) {
  const NosePoint noses[1] = {nose};
  const Vec3 targets[1] = {target};
  detail::check_inputs(curve, noses, targets);
  StepResult out;
  out.curve = curve;
  out.delta_points.assign(curve.control_points.size(), Vec3::Zero());
  out.delta_weights.assign(curve.control_points.size(), 0.0);
  const detail::BasisRow row = detail::basis_row(curve, nose);
  const int i = nose.nose_control;
  const double coefficient = row.values[i - row.first] * curve.weight(i);
  if (!(coefficient > 0.0)) {
    out.applicable = false;
    out.message = "the nose control point has no influence at the nose parameter";
    return out;
  }
  // Eq. 5: dB = S (P - C) / (N_i W_i); exact by eq. 3 since only B_i moves.
  const Vec3 delta = row.weight_sum / coefficient * (target - curve.evaluate(nose.u));
  out.curve.control_points[i] += delta;
  out.delta_points[i] = delta;
  out.exact = true;
  out.message = "eq. 5: moved control point " + std::to_string(i);
  return out;
}

StepResult move_control_points(const NurbsCurve& curve, std::span<const NosePoint> noses,
                               std::span<const Vec3> targets) {
  detail::check_inputs(curve, noses, targets);
  StepResult out;
  out.curve = curve;
  const int count = curve.count();
  out.delta_points.assign(count, Vec3::Zero());
  out.delta_weights.assign(count, 0.0);
  const int free = count - 2;  // the first and last control points stay fixed (eq. 7)
  const int n = static_cast<int>(noses.size());
  if (free <= 0 || n == 0) {
    out.applicable = false;
    out.message = "no free control points (the end control points are fixed)";
    return out;
  }
  // Eq. 6 / 7: rows b_{j,i} = N_i(t_j) W_i over the free control points, right-hand side
  // a_j dC_j = S_j (P_j - C(t_j)); one solve serves x, y and z (same matrix).
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, free);
  Eigen::MatrixXd r(n, 3);
  for (int j = 0; j < n; ++j) {
    const detail::BasisRow row = detail::basis_row(curve, noses[j]);
    for (int k = 0; k <= curve.degree; ++k) {
      const int i = row.first + k;
      if (i >= 1 && i <= count - 2) a(j, i - 1) = row.values[k] * curve.weight(i);
    }
    r.row(j) = (row.weight_sum * (targets[j] - curve.evaluate(noses[j].u))).transpose();
  }
  const detail::LinearSolution sol = detail::solve_linear(a, r);
  for (int i = 1; i <= count - 2; ++i) {
    Vec3 d = sol.x.row(i - 1).transpose();
    if (curve.dimension == 2) d.z() = 0.0;
    out.delta_points[i] = d;
    out.curve.control_points[i] += d;
  }
  out.residual = sol.residual;
  out.exact = sol.residual <= detail::kExactResidual;
  out.message = "eq. 7: " + std::to_string(n) + " equations, " + std::to_string(free) +
                " free control points, rank " + std::to_string(sol.rank) +
                (out.exact ? " (exact)" : " (least squares)");
  return out;
}

namespace {

// Why eqs. 20-21 cannot be applied to this curve, or nothing.
std::optional<std::string> joining_knots_unsupported(const NurbsCurve& curve) {
  if (curve.degree != 2) return "joining-knot positioning (eqs. 20-21) needs degree 2";
  const int count = curve.count();
  const auto& x = curve.knots;
  if (!(x[0] == x[2] && x[count] == x[count + 2])) {
    return "joining-knot positioning (eqs. 20-21) needs a clamped knot vector";
  }
  for (int s = 2; s < count; ++s) {
    if (!(x[s] < x[s + 1])) {
      return "joining-knot positioning (eqs. 20-21) needs simple interior knots";
    }
  }
  return std::nullopt;
}

}  // namespace

// Eqs. 20-21 (Appendix A11-A16), re-derived with 0-based indices. A clamped quadratic curve
// with control points B_0..B_{n+1} and spans D_k = x_{k+3} - x_{k+2} (k = 0..n-1) has the joining
// point between segments k and k+1 at x_{k+3}, where only N_{k+1} = D_{k+1}/(D_k + D_{k+1}) and
// N_{k+2} = D_k/(D_k + D_{k+1}) are non-zero (the printed A10 repeats A9's numerator: a typo), so
//     F_{k+1} = (D_{k+1} W_{k+1} B_{k+1} + D_k W_{k+2} B_{k+2}) / (D_{k+1} W_{k+1} + D_k W_{k+2}).
// F lies on the edge B_{k+1}B_{k+2} at F = (1 - l) B_{k+1} + l B_{k+2} with
//     l = D_k W_{k+2} / (D_{k+1} W_{k+1} + D_k W_{k+2}),
// hence D_{k+1} = D_k W_{k+2} (1 - l) / (W_{k+1} l), which is eq. 20 with the vector ratio
// (B_{k+2} - F)/(F - B_{k+1}) read as the scalar ratio (1 - l)/l; chaining gives eq. 21. A point
// off the edge cannot be a joining point of this polygon, so l is taken from its orthogonal
// projection onto the edge (exact when it lies on the edge, as after weight-only changes).
StepResult position_joining_knots(const NurbsCurve& curve, std::span<const Vec3> joins) {
  StepResult out;
  out.curve = curve;
  out.delta_points.assign(curve.control_points.size(), Vec3::Zero());
  out.delta_weights.assign(curve.control_points.size(), 0.0);
  if (auto e = curve.validate()) throw std::invalid_argument("curve \"" + curve.name + "\": " + *e);
  if (auto why = joining_knots_unsupported(curve)) {
    out.applicable = false;
    out.message = *why;
    return out;
  }
  const int count = curve.count();
  const int n = count - 2;  // segments
  if (static_cast<int>(joins.size()) != n - 1) {
    throw std::invalid_argument("curve \"" + curve.name + "\": " + std::to_string(joins.size()) +
                                " joining points for " + std::to_string(n) + " segments");
  }
  const auto& b = curve.control_points;
  std::vector<double> spans(n);
  spans[0] = curve.knots[3] - curve.knots[2];
  double worst_offset = 0.0;
  bool clamped_ratio = false;
  for (int k = 0; k + 1 < n; ++k) {
    const Vec3 edge = b[k + 2] - b[k + 1];
    const double len2 = edge.squaredNorm();
    double l = len2 > 0.0 ? (joins[k] - b[k + 1]).dot(edge) / len2 : 0.5;
    worst_offset = std::max(worst_offset, (b[k + 1] + l * edge - joins[k]).norm());
    // A joining point outside the open edge would need a zero or negative span.
    constexpr double kMinRatio = 1e-6;
    if (l < kMinRatio || l > 1.0 - kMinRatio) {
      clamped_ratio = true;
      l = std::clamp(l, kMinRatio, 1.0 - kMinRatio);
    }
    spans[k + 1] = spans[k] * curve.weight(k + 2) * (1.0 - l) / (curve.weight(k + 1) * l);
  }
  std::vector<double>& x = out.curve.knots;
  for (int k = 0; k < n; ++k)
    x[k + 3] = x[k + 2] + spans[k];
  x[count + 1] = x[count];
  x[count + 2] = x[count];
  out.residual = worst_offset;
  double scale = 1.0;
  for (const Vec3& p : b)
    scale = std::max(scale, p.norm());
  out.exact = worst_offset <= 1e-12 * scale && !clamped_ratio;
  out.message =
      std::string("eqs. 20-21: knot spans re-positioned") +
      (clamped_ratio ? "; a joining point lies outside its edge (span ratio clamped)" : "");
  return out;
}

}  // namespace nurbsreg::engine
