// Ma & Hewitt's control-polygon method (seed paper 000, Algorithms 1, 3 and 5, then
// Newton-Raphson), implemented as published so that it can be compared with circular clipping.
// Its Theorem 1 (Algorithm 3) is not a theorem: the 3-D argument (projection onto the plane
// of the first two edges, Figs. 11-12) and the mixed case "behind P_0 but beyond the chord's
// far end" are unproven, and Chen et al. 2007 give a counterexample. A second weakness: a
// control polygon folded back along its chord is "flat enough" (§6), its chord projection is a
// poor candidate, and the nearest candidate is chosen before Newton runs. The tests exhibit
// both rather than hide them.
#include <algorithm>
#include <cmath>

#include "curve/curve_local_solve.hpp"
#include "reference/curve_ma_hewitt.hpp"

namespace nurbsreg::engine::detail {
namespace {

// Sub-curves are split until flat or this deep (the paper's "recursion limit").
constexpr int kMaxDepth = 20;
// "Flat enough" (§6): every control point within this fraction of the chord length from the
// chord, so projecting onto the chord is a good Newton start.
constexpr double kFlatness = 1e-3;

// Algorithm 1 (Is_Valid_Polygon): every interior vertex P_i must lie on the other side of the
// line P_{i-1} P_{i+1} than the far end point (P_n for i < n/2, else P_0), tested by the dot
// product of the two perpendicular offsets from that line ("R > 0: concave direction").
bool is_valid_polygon(const Vec3* P, int n) {
  for (int i = 1; i < n; ++i) {
    const Vec3 a = P[i - 1];
    const Vec3 e = P[i + 1] - a;
    const double len2 = e.squaredNorm();
    if (len2 == 0.0) return false;
    const Vec3 v1 = a + ((P[i] - a).dot(e) / len2) * e;
    const Vec3 far = 2 * i < n ? P[n] : P[0];
    const Vec3 v2 = a + ((far - a).dot(e) / len2) * e;
    if ((P[i] - v1).dot(far - v2) > 0.0) return false;
  }
  return true;
}

// Algorithm 3 (Point_Nearest_Bézier_Curve), Theorem 1: returns false when the theorem claims
// that the nearest point of the sub-curve is one of its end points (then it is discarded).
// Read as (R1 < 0 or R2 < 0) and R3 R4 > 0: outside the end-tangent strip and outside the
// chord strip (Lemma 1's proof: areas A P0 Pn B and C P0 Pn D).
bool point_nearest_bezier_curve(const Vec3* P, int n, const Vec3& p) {
  const double r1 = (p - P[0]).dot(P[1] - P[0]);
  const double r2 = (P[n] - p).dot(P[n] - P[n - 1]);
  const double r3 = (P[0] - P[n]).dot(p - P[n]);
  const double r4 = (P[0] - P[n]).dot(p - P[0]);
  return !((r1 < 0.0 || r2 < 0.0) && r3 * r4 > 0.0);
}

bool is_flat(const Vec3* P, int n) {
  const Vec3 chord = P[n] - P[0];
  const double len2 = chord.squaredNorm();
  if (len2 == 0.0) return false;
  double worst = 0.0;
  for (int i = 1; i < n; ++i) {
    const Vec3 d = P[i] - P[0];
    worst = std::max(worst, (d - (d.dot(chord) / len2) * chord).squaredNorm());
  }
  return worst <= kFlatness * kFlatness * len2;
}

struct Search {
  const PreparedCurvePiece& pc;
  const Vec3& q;
  MaHewittCandidate& best;
  CurveProjectionStats& stats;

  void consider(double t) {
    Vec3 c;
    pc.evaluate_local(t, 0, &c);
    const double d2 = (c - q).squaredNorm();
    ++stats.local_solves;
    if (d2 < best.d2) best = {t, d2, true};
  }

  // Algorithm 5 (Nearest_Candidate_Points_Curve) on a sub-curve whose `param` is the local
  // interval of the piece.
  void recurse(const BezierCurve& sub, bool valid, int depth) {
    const int n = sub.degree;
    Vec3 P[kMaxDegree + 1];
    for (int i = 0; i <= n; ++i)
      P[i] = sub.point(i);
    const auto chord_candidate = [&] {
      const Vec3 chord = P[n] - P[0];
      const double len2 = chord.squaredNorm();
      const double s = len2 > 0.0 ? std::clamp((q - P[0]).dot(chord) / len2, 0.0, 1.0) : 0.0;
      consider(sub.param.to_parent(s));
    };
    if (valid) {
      if (!point_nearest_bezier_curve(P, n, q)) {
        // Theorem 1: "the nearest point must be one of the end points".
        ++stats.eliminated;
        consider(sub.param.lo);
        consider(sub.param.hi);
        return;
      }
      if (is_flat(P, n) || depth >= kMaxDepth) {
        chord_candidate();
        return;
      }
    } else if (is_valid_polygon(P, n)) {
      valid = true;
    } else if (is_flat(P, n) || depth >= kMaxDepth) {
      // §5: "until we get a valid control polygon or the control polygon is flat enough".
      chord_candidate();
      return;
    }
    ++stats.subdivisions;
    BezierCurve left;
    BezierCurve right;
    sub.split(0.5, left, right);
    recurse(left, valid, depth + 1);
    recurse(right, valid, depth + 1);
  }
};

}  // namespace

void ma_hewitt_candidates(const PreparedCurvePiece& pc, const Vec3& q, MaHewittCandidate& best,
                          CurveProjectionStats& stats) {
  BezierCurve sub;
  sub.degree = pc.degree;
  sub.cw = pc.local;  // the piece in its local frame, local parameter [0, 1]
  sub.param = {0.0, 1.0};
  ++stats.pieces_clipped;
  Search{pc, q, best, stats}.recurse(sub, false, 0);
}

LocalMinimum ma_hewitt_newton(const PreparedCurvePiece& pc, const Vec3& q, double t,
                              std::uint64_t& iterations) {
  // Plain Newton-Raphson on (C - q).C' = 0 from the candidate, kept inside the piece (§9:
  // on the Bézier piece rather than the whole curve).
  Vec3 d[3];
  for (int it = 0; it < 50; ++it) {
    pc.evaluate_local(t, 2, d);
    ++iterations;
    const Vec3 r = d[0] - q;
    const double g = r.dot(d[1]);
    const double gp = d[1].squaredNorm() + r.dot(d[2]);
    if (!(gp > 0.0)) break;
    const double next = std::clamp(t - g / gp, 0.0, 1.0);
    // Converged when the step moves the point by a negligible fraction of the extent.
    const bool done = std::abs(next - t) * d[1].norm() <= 1e-10 * (pc.radius + r.norm());
    t = next;
    if (done) break;
  }
  pc.evaluate_local(t, 0, d);
  return {t, (d[0] - q).squaredNorm(), d[0]};
}

}  // namespace nurbsreg::engine::detail

namespace nurbsreg::engine {

bool project_onto_piece_ma_hewitt(const PreparedCurvePiece& pc, const Vec3& p, CurveHit& best,
                                  CurveProjectionStats* stats) {
  CurveProjectionStats local;
  const Vec3 q = p - pc.origin;
  detail::MaHewittCandidate candidate;
  detail::ma_hewitt_candidates(pc, q, candidate, local);
  bool improved = false;
  if (candidate.found) {
    const detail::LocalMinimum r =
        detail::ma_hewitt_newton(pc, q, candidate.t, local.newton_iterations);
    Vec3 c;
    pc.evaluate_local(candidate.t, 0, &c);
    // Newton polishes the candidate; keep whichever is closer.
    if (r.d2 <= candidate.d2) {
      improved = detail::offer(pc, r.t, r.d2, r.point, best);
    } else {
      improved = detail::offer(pc, candidate.t, candidate.d2, c, best);
    }
  }
  if (stats) *stats += local;
  return improved;
}

}  // namespace nurbsreg::engine
