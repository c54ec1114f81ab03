// Per-piece preparation and circular clipping on one rational Bézier piece (seed paper 002).
#include <algorithm>
#include <cmath>
#include <limits>

#include "bernstein/bernstein_clipping.hpp"
#include "bernstein/binomial_table.hpp"
#include "curve/curve_local_solve.hpp"
#include "nurbsreg/engine/curve_projection.hpp"

namespace nurbsreg::engine {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

// Up to 2 * kMaxDegree (Bézier products).
constexpr BinomialTable<kMaxBernsteinDegree> kBinomials;

}  // namespace

CurveProjectionStats& CurveProjectionStats::operator+=(const CurveProjectionStats& o) {
  queries += o.queries;
  pieces_pruned += o.pieces_pruned;
  pieces_clipped += o.pieces_clipped;
  subdivisions += o.subdivisions;
  eliminated += o.eliminated;
  local_solves += o.local_solves;
  newton_iterations += o.newton_iterations;
  depth_limit_hits += o.depth_limit_hits;
  return *this;
}

PreparedCurvePiece prepare_curve_piece(const BezierCurve& piece) {
  PreparedCurvePiece out;
  out.piece = piece;
  const int n = piece.degree;
  out.degree = n;
  out.box = bounding_box(piece);
  out.origin = out.box.center();
  Vec3 rel[kMaxDegree + 1];
  double w[kMaxDegree + 1];
  double r2 = 0.0;
  for (int i = 0; i <= n; ++i) {
    w[i] = piece.weight(i);
    rel[i] = piece.point(i) - out.origin;
    r2 = std::max(r2, rel[i].squaredNorm());
    out.local[i] << w[i] * rel[i], w[i];
  }
  out.radius = std::sqrt(r2);
  for (int i = 0; i < n; ++i)
    out.d1[i] = n * (out.local[i + 1] - out.local[i]);
  for (int i = 0; i + 1 < n; ++i)
    out.d2[i] = (n - 1) * (out.d1[i + 1] - out.d1[i]);
  // Bernstein product B_i^n B_j^n = c_ij B_{i+j}^{2n}, c_ij = C(n,i) C(n,j) / C(2n,i+j)
  // (DESIGN.md "Projection: curves"; seed 002 eq. (2)).
  for (int k = 0; k <= 2 * n; ++k) {
    out.W[k] = out.G[k] = 0.0;
    out.E[k].setZero();
  }
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const int k = i + j;
      const double c = kBinomials.c[n][i] * kBinomials.c[n][j] / kBinomials.c[2 * n][k];
      const double ww = c * w[i] * w[j];
      out.W[k] += ww;
      out.G[k] += ww * rel[i].dot(rel[j]);
      out.E[k] += (0.5 * ww) * (rel[i] + rel[j]);
    }
  }
  return out;
}

namespace {

// C, C', C'' of the piece in its local frame at t. N > 0 is the degree when known at compile
// time (the loops unroll: this is the innermost call of every Newton step), 0 for any degree.
template <int N>
void evaluate_piece(const PreparedCurvePiece& pc, double t, int order, Vec3* derivs) {
  const int n = N > 0 ? N : pc.degree;
  // Bernstein rows n, n-1, n-2 from one triangular pass (The NURBS Book A1.3).
  double b[kMaxDegree + 1];
  double b1[kMaxDegree + 1];
  double b2[kMaxDegree + 1];
  const double s = 1.0 - t;
  b[0] = 1.0;
  b1[0] = 1.0;
  b2[0] = 1.0;
  for (int j = 1; j <= n; ++j) {
    double saved = 0.0;
    for (int k = 0; k < j; ++k) {
      const double temp = b[k];
      b[k] = saved + s * temp;
      saved = t * temp;
    }
    b[j] = saved;
    if (j == n - 2) std::copy(b, b + j + 1, b2);
    if (j == n - 1) std::copy(b, b + j + 1, b1);
  }
  Vec4 a0 = Vec4::Zero();
  for (int i = 0; i <= n; ++i)
    a0 += b[i] * pc.local[i];
  const double inv_w = 1.0 / a0[3];
  derivs[0] = a0.head<3>() * inv_w;
  if (order < 1) return;
  Vec4 a1 = Vec4::Zero();
  for (int i = 0; i < n; ++i)
    a1 += b1[i] * pc.d1[i];
  derivs[1] = (a1.head<3>() - a1[3] * derivs[0]) * inv_w;
  if (order < 2) return;
  Vec4 a2 = Vec4::Zero();
  for (int i = 0; i + 1 < n; ++i)
    a2 += b2[i] * pc.d2[i];
  // Quotient rule for rational curves (The NURBS Book eq. 4.8).
  derivs[2] = (a2.head<3>() - 2.0 * a1[3] * derivs[1] - a2[3] * derivs[0]) * inv_w;
}

}  // namespace

void PreparedCurvePiece::evaluate_local(double t, int order, Vec3* derivs) const {
  switch (degree) {
    case 1:
      return evaluate_piece<1>(*this, t, order, derivs);
    case 2:
      return evaluate_piece<2>(*this, t, order, derivs);
    case 3:
      return evaluate_piece<3>(*this, t, order, derivs);
    case 4:
      return evaluate_piece<4>(*this, t, order, derivs);
    case 5:
      return evaluate_piece<5>(*this, t, order, derivs);
    case 6:
      return evaluate_piece<6>(*this, t, order, derivs);
    default:
      return evaluate_piece<0>(*this, t, order, derivs);
  }
}

namespace detail {

double piece_parameter(const PreparedCurvePiece& pc, double t) {
  if (t <= 0.0) return pc.piece.param.lo;
  if (t >= 1.0) return pc.piece.param.hi;
  return pc.piece.param.to_parent(t);
}

bool offer(const PreparedCurvePiece& pc, double t, double d2, const Vec3& local_point,
           CurveHit& best) {
  // Strictly better by more than rounding: a second run over the same piece (or a piece that
  // shares the end point) keeps the answer it already has.
  if (!(d2 < best.distance_sq * (1.0 - 8.0 * kEps))) return false;
  best.u = piece_parameter(pc, t);
  best.distance_sq = d2;
  // End points are exact control points of the piece; elsewhere undo the local frame.
  if (t <= 0.0) {
    best.foot = pc.piece.point(0);
  } else if (t >= 1.0) {
    best.foot = pc.piece.point(pc.degree);
  } else {
    best.foot = pc.origin + local_point;
  }
  return true;
}

LocalMinimum safeguarded_newton(const PreparedCurvePiece& pc, const Vec3& q, double lo, double hi,
                                double t, std::uint64_t& iterations) {
  // Ye (1994) / "rtsafe": Newton on g(t) = (C(t) - q).C'(t), whose root in [lo, hi] is the
  // foot point, falling back to bisection whenever the Newton step leaves the bracket
  // g(lo) < 0 < g(hi) or does not halve the step; converges for any g with one sign change.
  t = std::clamp(t, lo, hi);
  double dx_old = hi - lo;
  double dx = dx_old;
  double last_newton = 0.0;  // previous Newton step, 0 after a bisection
  const double r2 = pc.radius * pc.radius;
  Vec3 d[3];
  for (int it = 0; it < 200; ++it) {
    pc.evaluate_local(t, 2, d);
    ++iterations;
    const Vec3 r = d[0] - q;
    const double g = r.dot(d[1]);
    const double gp = d[1].squaredNorm() + r.dot(d[2]);
    if (g < 0.0) {
      lo = t;
    } else if (g > 0.0) {
      hi = t;
    } else {
      return {t, r.squaredNorm(), d[0]};
    }
    // Convergence is judged on the geometry, not on |dx|: with extreme weights the speed |C'|
    // varies by orders of magnitude along a piece. Target: the cosine between C' and the
    // residual r, |g| / (|C'| |r|), below 1e-12 (seed 000's "zero-cosine"); floor: a step that
    // moves the point by less than the rounding of the extent (radius + |r|)^2 <=
    // 2 (radius^2 + |r|^2). Squared forms avoid square roots.
    const double speed2 = d[1].squaredNorm();
    const double rr = r.squaredNorm();
    const double scale2 = 2.0 * (r2 + rr);
    const bool newton_ok = gp > 0.0 && ((t - hi) * gp - g) * ((t - lo) * gp - g) < 0.0 &&
                           std::abs(2.0 * g) <= std::abs(dx_old * gp);
    dx_old = dx;
    double next;
    if (newton_ok) {
      dx = g / gp;
      next = t - dx;
      const double move2 = dx * dx * speed2;
      bool done = g * g <= 1e-24 * speed2 * rr || move2 <= 4096.0 * kEps * kEps * scale2;
      if (!done && last_newton != 0.0 && move2 <= 1e-12 * scale2) {
        // Quadratic convergence: the error after this step is about K dx^2, K estimated from
        // the last two steps (K = |dx| / last^2); predict the cosine after the step.
        const double predicted = std::abs(dx) / (last_newton * last_newton) * dx * dx;
        const double g_next = predicted * gp;
        done = g_next * g_next <= 1e-24 * speed2 * rr;
      }
      if (done) {
        t = std::clamp(next, lo, hi);
        break;
      }
      last_newton = dx;
    } else {
      dx = 0.5 * (hi - lo);
      next = lo + dx;
      last_newton = 0.0;
      // Stop when the bracket cannot shrink any more or is below the rounding of g.
      if (next <= lo || next >= hi || dx * dx * speed2 <= 16.0 * kEps * kEps * scale2) {
        t = next;
        break;
      }
    }
    t = next;
  }
  pc.evaluate_local(t, 0, d);
  return {t, (d[0] - q).squaredNorm(), d[0]};
}

}  // namespace detail

namespace {

// The local minimiser handed to circular_clip: works on the geometry, records the answer.
struct ClippingTerminal {
  const PreparedCurvePiece& pc;
  const Vec3& q;  // test point relative to pc.origin
  CurveHit& best;
  bool improved = false;
  std::uint64_t newton_iterations = 0;

  double candidate(double t, const Vec3& c) {
    const double d2 = (c - q).squaredNorm();
    improved |= detail::offer(pc, t, d2, c, best);
    return d2;
  }
  double candidate(double t) {
    Vec3 c;
    pc.evaluate_local(t, 0, &c);
    return candidate(t, c);
  }

  double operator()(const RationalBernstein& node, const double* f, TerminalReason why) {
    const int m = node.degree;
    int kmin = 0;
    for (int k = 1; k <= m; ++k) {
      if (f[k] < f[kmin]) kmin = k;
    }
    // Starting guess: the vertex of the parabola through the control values around the
    // smallest one (control value k sits near s = k/m).
    double s = static_cast<double>(kmin) / m;
    if (kmin > 0 && kmin < m) {
      const double curvature = f[kmin - 1] - 2.0 * f[kmin] + f[kmin + 1];
      if (curvature > 0.0) s += 0.5 * (f[kmin - 1] - f[kmin + 1]) / curvature / m;
    }
    const double guess = node.a + s * (node.b - node.a);
    if (why == TerminalReason::unimodal) {
      bool rising = true;
      bool falling = true;
      for (int k = 0; k < m; ++k) {
        rising &= f[k + 1] >= f[k];
        falling &= f[k + 1] <= f[k];
      }
      // Monotone control values: f is monotone (variation diminishing), minimum at an end.
      if (rising) return candidate(node.a);
      if (falling) return candidate(node.b);
      // Otherwise the one minimum is inside, with f' <= 0 at a and >= 0 at b: the end slopes
      // of a rational Bézier function have the signs of f_1 - f_0 and f_m - f_{m-1}, so
      // [a, b] brackets the root of g without evaluating the ends.
      const detail::LocalMinimum r =
          detail::safeguarded_newton(pc, q, node.a, node.b, guess, newton_iterations);
      improved |= detail::offer(pc, r.t, r.d2, r.point, best);
      return r.d2;
    }
    // Flat or depth-limited: no shape guarantee; bracket on the geometry itself.
    Vec3 da[2];
    Vec3 db[2];
    pc.evaluate_local(node.a, 1, da);
    pc.evaluate_local(node.b, 1, db);
    double found = std::min(candidate(node.a, da[0]), candidate(node.b, db[0]));
    const double ga = (da[0] - q).dot(da[1]);
    const double gb = (db[0] - q).dot(db[1]);
    if (ga < 0.0 && gb > 0.0) {
      const detail::LocalMinimum r =
          detail::safeguarded_newton(pc, q, node.a, node.b, guess, newton_iterations);
      improved |= detail::offer(pc, r.t, r.d2, r.point, best);
      found = std::min(found, r.d2);
    } else {
      found = std::min(found, candidate(guess));
    }
    return found;
  }
};

}  // namespace

bool project_onto_piece(const PreparedCurvePiece& pc, const Vec3& p, CurveHit& best,
                        CurveProjectionStats* stats) {
  const Vec3 q = p - pc.origin;
  const double qn = q.norm();
  // NaN would defeat every comparison below (nothing eliminated, nothing terminal).
  if (!std::isfinite(qn)) return false;
  // Bounding sphere: every point of the piece is at least |q| - radius away (rounding of that
  // difference absorbed by the 4 eps term).
  const double lower = qn - pc.radius - 4.0 * kEps * (qn + pc.radius);
  if (lower > 0.0 && lower * lower > best.distance_sq) {
    if (stats) ++stats->pieces_pruned;
    return false;
  }
  const int n = pc.degree;
  bool improved = false;
  // The end points are exact candidates (seed 002: alpha starts from them).
  const Vec3 c0 = pc.local[0].head<3>() / pc.local[0][3];
  const Vec3 cn = pc.local[n].head<3>() / pc.local[n][3];
  improved |= detail::offer(pc, 0.0, (c0 - q).squaredNorm(), c0, best);
  improved |= detail::offer(pc, 1.0, (cn - q).squaredNorm(), cn, best);

  RationalBernstein root;
  root.degree = 2 * n;
  root.depth = 0;
  root.speculative = false;
  root.a = 0.0;
  root.b = 1.0;
  const double qq = q.squaredNorm();
  for (int k = 0; k <= 2 * n; ++k) {
    root.num[k] = pc.G[k] - 2.0 * q.dot(pc.E[k]) + qq * pc.W[k];
    root.den[k] = pc.W[k];
  }
  // Every term of W_k f_k = sum c w_i w_j (P_i - p).(P_j - p) is at most (radius + |q|)^2 W_k
  // in size; a few roundings per coefficient plus one per halving (convex combinations) keep
  // the error of each f_k below this bound up to the maximal depth.
  const double extent = pc.radius + qn;
  const double noise = 256.0 * kEps * extent * extent;
  // Beyond ~1e150 the squared distances overflow: only the end points can be compared.
  if (!std::isfinite(noise)) return improved;
  double alpha = best.distance_sq;
  ClippingTerminal terminal{pc, q, best};
  ClippingCounters counters;
  circular_clip(root, noise, alpha, terminal, counters);
  improved |= terminal.improved;
  if (stats) {
    ++stats->pieces_clipped;
    stats->subdivisions += counters.subdivisions;
    stats->eliminated += counters.eliminated;
    stats->local_solves += counters.terminals;
    stats->depth_limit_hits += counters.depth_limit_hits;
    stats->newton_iterations += terminal.newton_iterations;
  }
  return improved;
}

}  // namespace nurbsreg::engine
