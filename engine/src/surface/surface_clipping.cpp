// Spherical clipping for rational Bézier patches (seed paper 001, extended to NURBS): the
// subdivision of one patch's squared-distance coefficients, Theorem 1 eliminations, edge
// reductions (Theorem 2, the monotone test, the 1-D clipping of a boundary row) and convex
// terminations finished by the box-constrained Newton (patch_newton.cpp). Its tests and kernels
// live beside it: derivative_bounds, coefficient_bounds, start_minimisers, patch_derivatives,
// bernstein/de_casteljau; the coefficients themselves in prepare_patch.cpp.

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>

#include "bernstein/de_casteljau.hpp"
#include "nurbsreg/engine/surface_projection.hpp"
#include "nurbsreg/engine/trim_region.hpp"
#include "platform/cpu_dispatch.hpp"
#include "surface/box_tests.hpp"
#include "surface/coefficient_bounds.hpp"
#include "surface/derivative_bounds.hpp"
#include "surface/patch_newton.hpp"
#include "surface/start_minimisers.hpp"

namespace nurbsreg::engine {
namespace {

// The state of one clipping run on one patch.
//
// kTrim: the patch may straddle a trim loop of its face (project_onto_patch's `region`). The
// untrimmed instantiation compiles to exactly the former code. In the trimmed one every box
// carries `straddling`: a box proven inside the region (TrimRegion::classify) runs exactly as an
// untrimmed box (all its points are face points, so every proof below holds as is); children of an
// inside box are inside; a straddling box's children are classified again and dropped when proven
// outside. In a straddling box, with R the region and "the edges" the face's trim edges, which
// the caller projects onto as well (so every loop point's distance is already covered):
//  - a candidate (corner coefficient, Newton result, boundary-clipping value) is offered only if
//    its (u, v) is in R (`active` is the region then; offers outside R are rejected);
//  - Theorem 2 (boundary_edge) is NOT used: it proves F(s0, t) <= F(s, t), but the path from
//    (s, t) to the edge may leave R, so the edge's minimum over R need not bound the box's.
//  - the monotone edge reduction IS used: if F_s > 0 on the box, move from any x in box ∩ R
//    towards s = s0 along s: F decreases, and the segment either reaches the edge inside R (a
//    point clip_boundary considers, with region-checked offers) or first leaves R, i.e. crosses
//    a trim loop (the box lies in the domain, so R's boundary there is a loop), whose points the
//    edges cover. Either way something already considered is at most F(x).
//  - convex termination: F has a unique minimiser x* on the box (Newton finds it). If x* is in
//    R, it is the minimum over box ∩ R. If not, drop the box: for x in box ∩ R the segment
//    [x, x*] stays in the (convex) box, F decreases along it (convexity), and it leaves R, i.e.
//    crosses a loop, covered by the edges. The same in 1-D inside clip_boundary.
//  - resolution and depth-limit terminations (safety nets): the Newton point is accepted only if
//    in R. For the resolution case nothing is lost beyond the accepted rounding: F varies by
//    <= 4 round_err over the box, and a box meeting R but whose Newton point is outside meets a
//    loop (edges within 4 round_err) or is all inside (then the point is in R).
//  - a monotone 1-D edge interval's end value (clip_boundary): offered only if in R; otherwise,
//    from any point of the interval in R move to that end: F decreases, and the path reaches the
//    end (in R: offered) or crosses a loop first (covered).
template <bool kTrim>
struct Clipper {
  const PreparedPatch& pp;
  const Vec3& p;
  SurfaceScratch& sc;
  SurfaceProjectionStats& st;
  double alpha;      // upper bound on the minimum squared distance
  double round_err;  // bound on rounding in any computed coefficient ratio
  double eps_d;      // accepted loss in distance when eliminating (relative to the patch size)
  double best_value = std::numeric_limits<double>::infinity();
  double best_s = 0, best_t = 0;
  bool best_exact = false;  // the best candidate is a Newton result on the geometry
  Vec3 best_foot = Vec3::Zero();
  Vec3 best_normal = Vec3::Zero();
  // Caller's guess of the minimiser (e.g. the previous ICP foot), local; NaN: none.
  double guess_s = std::numeric_limits<double>::quiet_NaN();
  double guess_t = std::numeric_limits<double>::quiet_NaN();
  // kTrim: the face's region, and the region to check offers against for the current box (the
  // region in a straddling box, null in a box proven inside).
  const TrimRegion* region = nullptr;
  const TrimRegion* active = nullptr;

  // kTrim: may the local (s, t) be offered in the current box?
  bool admissible(double s, double t) const {
    if constexpr (kTrim) {
      if (active != nullptr &&
          !active->contains(pp.patch.param_u.to_parent(s), pp.patch.param_v.to_parent(t))) {
        ++st.region_rejections;
        return false;
      }
    }
    return true;
  }

  // Theorem 1 with an accuracy tolerance and a rounding margin: drop the box when its lower bound,
  // even lowered by the rounding bound, shows that no point of the box is closer than
  // sqrt(alpha) - eps_d. Where round_err exceeds that tolerance this is conservative.
  bool eliminated(double lower) const {
    if (!std::isfinite(alpha)) return false;
    const double target = std::max(std::sqrt(alpha) - eps_d, 0.0);
    return lower - round_err >= target * target;
  }
  // A value known only through coefficients (corner values): its bound is value + round_err.
  void offer_coefficient(double value, double s, double t) {
    if constexpr (kTrim) {
      // Only a value that could matter pays for the region test.
      if (value + round_err >= alpha && value >= best_value) return;
      if (!admissible(s, t)) return;
    }
    if (value < best_value) {
      best_value = value;
      best_s = s;
      best_t = t;
      best_exact = false;
    }
    alpha = std::min(alpha, value + round_err);
  }
  // A value of the real geometry (Newton result).
  void offer_exact(double value, double s, double t, const Vec3& foot, const Vec3& normal) {
    if (value < best_value) {
      best_value = value;
      best_s = s;
      best_t = t;
      best_exact = true;
      best_foot = foot;
      best_normal = normal;
    }
    alpha = std::min(alpha, value);
  }
  // Box-constrained Newton on [s0, s1] x [t0, t1] from (s, t). Where it starts does not affect
  // correctness (it is called where the minimiser on the box is unique, or as a safety net), only
  // the number of iterations; the start is, in order of preference: the best Newton point so far
  // when it lies in this box (neighbouring boxes often share the minimiser), the caller's guess
  // when it lies in the box (warm start), else (s, t) from the caller (the abscissa of the
  // smallest coefficient of F on the box).
  // convex: F is proven convex on the box (polynomial patch): Newton may stop as soon as its
  // tangent plane shows the box cannot hold a point that survives `eliminated`.
  // Does newton() start from a point of its own on this box (see there)?
  bool has_start(double s0, double s1, double t0, double t1) const {
    return (best_exact && best_s >= s0 && best_s <= s1 && best_t >= t0 && best_t <= t1) ||
           (guess_s >= s0 && guess_s <= s1 && guess_t >= t0 && guess_t <= t1);
  }
  void newton(double s0, double s1, double t0, double t1, double s, double t, bool convex = false) {
    if (best_exact && best_s >= s0 && best_s <= s1 && best_t >= t0 && best_t <= t1) {
      s = best_s;
      t = best_t;
    } else if (guess_s >= s0 && guess_s <= s1 && guess_t >= t0 && guess_t <= t1) {
      s = guess_s;
      t = guess_t;
    }
    double abort_at = std::numeric_limits<double>::infinity();
    if (convex && std::isfinite(alpha)) {
      // The same threshold as `eliminated` (a lower bound >= it drops a box).
      const double target = std::max(std::sqrt(alpha) - eps_d, 0.0);
      abort_at = target * target + round_err;
    }
    Vec3 foot, normal;
    const double value = newton_core(pp, p, s0, s1, t0, t1, s, t, foot, &st, &normal, abort_at);
    if (std::isfinite(value) && admissible(s, t)) offer_exact(value, s, t, foot, normal);
  }

  // The row (stride 1) or column (stride cols) of N and D along an edge of the current box.
  void clip_boundary(const double* n_row, const double* d_row, int stride, int count, bool along_t,
                     double fixed, double a0, double a1);
  void reduce_to_edge(int edge, const double* n, const double* d, const SurfaceScratch::Box& b) {
    ++st.boundary_reductions;
    const int rows = pp.rows, cols = pp.cols;
    if (edge <= 1) {
      const int offset = edge == 0 ? 0 : (rows - 1) * cols;
      clip_boundary(n + offset, d + offset, 1, cols, true, edge == 0 ? b.s0 : b.s1, b.t0, b.t1);
    } else {
      const int offset = edge == 2 ? 0 : cols - 1;
      clip_boundary(n + offset, d + offset, cols, rows, false, edge == 2 ? b.t0 : b.t1, b.s0, b.s1);
    }
  }
  void run();
};

// 1-D spherical clipping on a boundary row of F (seed 002's circular clipping applied to the
// boundary curve's squared distance, whose rational Bernstein coefficients are that row of N and
// D): elimination by the minimum coefficient ratio; termination, for a polynomial row, when the
// coefficient differences change sign at most once from - to + (Property 2 of seed 002: one
// minimum on the interval) and, for a rational row, when F_t is provably of one sign (the minimum
// is an end value) or F_tt > 0 (convex: one minimum). The minimum is then found by Newton on the
// boundary curve of the surface itself.
template <bool kTrim>
void Clipper<kTrim>::clip_boundary(const double* n_row, const double* d_row, int stride, int count,
                                   bool along_t, double fixed, double a0, double a1) {
  constexpr int kLine = 2 * kMaxDegree + 1;
  const bool rational = pp.rational;
  auto ratio_min = [&](const double* n, const double* d) {
    double lo = std::numeric_limits<double>::infinity();
    for (int j = 0; j < count; ++j)
      lo = std::min(lo, rational ? n[j] / d[j] : n[j]);
    return lo;
  };
  // Newton on the edge from the abscissa of the row's smallest coefficient ratio.
  auto newton_on = [&](double lo, double hi, const double* c, const double* w) {
    int arg = 0;
    double lo_value = std::numeric_limits<double>::infinity();
    for (int j = 0; j < count; ++j) {
      const double r = rational ? c[j] / w[j] : c[j];
      if (r < lo_value) {
        lo_value = r;
        arg = j;
      }
    }
    double x = count > 1 ? lo + (hi - lo) * arg / (count - 1) : 0.5 * (lo + hi);
    if (!rational && count > 2) {
      // A start at the polynomial row's own minimiser (see bernstein_minimiser).
      x = lo + (hi - lo) * bernstein_minimiser(c, count, double(arg) / (count - 1));
    }
    if (along_t) {
      newton(fixed, fixed, lo, hi, fixed, x);
    } else {
      newton(lo, hi, fixed, fixed, x, fixed);
    }
  };
  int top = 0;
  double* base = sc.rows.data();
  for (int j = 0; j < count; ++j) {
    base[j] = n_row[j * stride];
    base[kLine + j] = d_row[j * stride];
  }
  sc.intervals[top++] = {a0, a1, ratio_min(base, base + kLine), 0};
  while (top > 0) {
    const SurfaceScratch::Interval iv = sc.intervals[--top];
    double* c = base + top * 2 * kLine;
    double* w = c + kLine;
    if (eliminated(iv.lower)) {
      ++st.eliminations;
      continue;
    }
    offer_coefficient(c[0] / w[0], along_t ? fixed : iv.t0, along_t ? iv.t0 : fixed);
    offer_coefficient(c[count - 1] / w[count - 1], along_t ? fixed : iv.t1,
                      along_t ? iv.t1 : fixed);
    double c_max = -std::numeric_limits<double>::infinity();
    for (int j = 0; j < count; ++j)
      c_max = std::max(c_max, rational ? c[j] / w[j] : c[j]);
    if (c_max - iv.lower <= 4.0 * round_err) {  // below the coefficients' resolution
      ++st.resolution_terminations;
      newton_on(iv.t0, iv.t1, c, w);
      continue;
    }
    if (!rational) {
      int changes = 0;
      int last_sign = 0;
      bool falls_first = false;
      for (int j = 0; j + 1 < count; ++j) {
        const double delta = c[j + 1] - c[j];
        const int sign = delta > 0 ? 1 : (delta < 0 ? -1 : 0);
        if (sign == 0) continue;
        if (last_sign == 0) falls_first = sign < 0;
        if (last_sign != 0 && sign != last_sign) ++changes;
        last_sign = sign;
      }
      if (changes == 0) continue;  // monotone: the minimum is an end value, already offered
      if (changes == 1 && falls_first) {
        ++st.convex_terminations;
        newton_on(iv.t0, iv.t1, c, w);
        continue;
      }
    } else {
      // A 1 x count grid: the same derivative bounds with no s direction.
      const FDerivatives f = f_derivatives(c, w, 1, count, true, {iv.lower, c_max});
      const double margin = 1e-12 * std::max(std::abs(f.t.lo), std::abs(f.t.hi));
      if (f.t.lo > margin || f.t.hi < -margin) continue;  // monotone: an end value
      if (f.tt.lo > 1e-12 * std::abs(f.tt.hi)) {
        ++st.convex_terminations;
        newton_on(iv.t0, iv.t1, c, w);
        continue;
      }
    }
    if (iv.depth >= SurfaceScratch::kMaxDepth || top + 2 > SurfaceScratch::kStackCapacity) {
      ++st.depth_limit_hits;
      newton_on(iv.t0, iv.t1, c, w);
      continue;
    }
    ++st.subdivisions;
    double* high = c + 2 * kLine;
    double* high_w = high + kLine;
    split_line(c, high, count);
    if (rational) {
      split_line(w, high_w, count);
    } else {
      std::memcpy(high_w, w, sizeof(double) * count);
    }
    const double mid = 0.5 * (iv.t0 + iv.t1);
    const double low_lower = ratio_min(c, w);
    const double high_lower = ratio_min(high, high_w);
    SurfaceScratch::Interval first{iv.t0, mid, low_lower, iv.depth + 1};  // data in slot top
    SurfaceScratch::Interval second{mid, iv.t1, high_lower, iv.depth + 1};
    // Visit the more promising half first: it goes on top of the stack.
    if (low_lower < high_lower) {
      std::swap_ranges(c, c + 2 * kLine, high);
      std::swap(first, second);
    }
    sc.intervals[top++] = first;
    sc.intervals[top++] = second;
  }
}

template <bool kTrim>
[[gnu::always_inline]] inline void Clipper<kTrim>::run() {
  const int rows = pp.rows, cols = pp.cols, count = rows * cols;
  constexpr int kSlot = 2 * SurfaceScratch::kGridCapacity;
  double* base = sc.grids.data();
  int top = 0;
  pp.numerator(p, base);
  // A polynomial patch has D == 1 everywhere and never splits it: every box reads the patch's
  // own array instead of a copy.
  if (pp.rational) {
    std::memcpy(base + SurfaceScratch::kGridCapacity, pp.d.data(), sizeof(double) * count);
  }
  auto d_of = [&](double* n) {
    return pp.rational ? n + SurfaceScratch::kGridCapacity : pp.d.data();
  };
  const CoefficientRange root = coefficient_range(base, d_of(base), count, pp.rational);
  // A trimmed run starts from a patch the caller classified as straddling.
  sc.boxes[top++] = {0.0, 1.0, 0.0, 1.0, root.lo, root.hi, root.arg, 0, kTrim};
  while (top > 0) {
    const SurfaceScratch::Box b = sc.boxes[--top];
    if constexpr (kTrim) active = b.straddling ? region : nullptr;
    double* n = base + top * kSlot;
    const double* d = d_of(n);
    // Newton on this box, started at the Greville abscissa (i / (rows - 1), j / (cols - 1)) of
    // F's smallest coefficient: near the minimiser when the box is nearly convex.
    auto newton_box = [&](bool convex = false) {
      const int arg = b.arg >= 0    ? b.arg
                      : pp.rational ? first_ratio_index_of(n, d, count, b.lower)
                                    : first_index_of(n, count, b.lower);
      const int i = arg / cols, j = arg % cols;
      double s = rows > 1 ? b.s0 + (b.s1 - b.s0) * i / (rows - 1) : 0.5 * (b.s0 + b.s1);
      double t = cols > 1 ? b.t0 + (b.t1 - b.t0) * j / (cols - 1) : 0.5 * (b.t0 + b.t1);
      // A polynomial F proven convex on the box: start at its own minimiser (polynomial_start)
      // unless newton() has a better start of its own.
      if (convex && !pp.rational && !has_start(b.s0, b.s1, b.t0, b.t1)) {
        double u = rows > 1 ? double(i) / (rows - 1) : 0.5;
        double v = cols > 1 ? double(j) / (cols - 1) : 0.5;
        if (polynomial_start(n, rows, cols, u, v)) {
          s = b.s0 + (b.s1 - b.s0) * u;
          t = b.t0 + (b.t1 - b.t0) * v;
        }
      }
      newton(b.s0, b.s1, b.t0, b.t1, s, t, convex);
    };
    if (eliminated(b.lower)) {
      ++st.eliminations;
      continue;
    }
    // Corner values are exact values of F: they shrink the clipping sphere (seed 001 §2).
    const int c00 = 0, c01 = cols - 1, c10 = (rows - 1) * cols, c11 = count - 1;
    offer_coefficient(n[c00] / d[c00], b.s0, b.t0);
    offer_coefficient(n[c01] / d[c01], b.s0, b.t1);
    offer_coefficient(n[c10] / d[c10], b.s1, b.t0);
    offer_coefficient(n[c11] / d[c11], b.s1, b.t1);
    if (eliminated(b.lower)) {
      ++st.eliminations;
      continue;
    }
    // Theorem 2 does not hold along paths inside a trimmed region (see Clipper): not for a
    // straddling box.
    if (!pp.rational && !(kTrim && b.straddling)) {
      const int edge = boundary_edge(n, rows, cols);
      if (edge >= 0) {
        reduce_to_edge(edge, n, d, b);
        continue;
      }
    }
    const double f_max = b.upper;
    // F is known to +-round_err only: once its whole range on the box is within a few round_err
    // the coefficients cannot resolve the box further (a point on or within ~sqrt(round_err) of
    // the surface, or a pole where F is flat across the box). The geometry can: Newton finishes.
    if (f_max - b.lower <= 4.0 * round_err) {
      ++st.resolution_terminations;
      newton_box();
      continue;
    }
    if (!pp.rational) {
      if (convex_polynomial(n, rows, cols)) {
        ++st.convex_terminations;
        newton_box(true);
        continue;
      }
      if constexpr (kTrim) {
        // In place of Theorem 2 in a straddling box: the monotone edge reduction (valid there,
        // see Clipper) on F's own derivative bounds.
        if (b.straddling) {
          const int edge = polynomial_monotone_edge(n, rows, cols);
          if (edge >= 0) {
            reduce_to_edge(edge, n, d, b);
            continue;
          }
        }
      }
    } else {
      const int edge = rational_box_test(n, d, rows, cols, b.lower, f_max);
      if (edge == kConvexBox) {
        ++st.convex_terminations;
        newton_box();
        continue;
      }
      if (edge >= 0) {
        reduce_to_edge(edge, n, d, b);
        continue;
      }
    }
    if (b.depth >= SurfaceScratch::kMaxDepth || top + 2 > SurfaceScratch::kStackCapacity) {
      ++st.depth_limit_hits;
      newton_box();
      continue;
    }
    ++st.subdivisions;
    // Split across the direction in which F varies most: that is where the box is "long". F's
    // coefficients are N's, or N / D's for a rational patch: those ratios are taken once each (a
    // vector loop) rather than once per neighbour; max is order-independent, so the same maxima.
    const double* f = n;
    double ratios[SurfaceScratch::kGridCapacity];
    if (pp.rational) {
      for (int k = 0; k < count; ++k)
        ratios[k] = n[k] / d[k];
      f = ratios;
    }
    double var_s = 0.0, var_t = 0.0;
    for (int k = 0; k + cols < count; ++k)
      var_s = std::max(var_s, std::abs(f[k + cols] - f[k]));
    for (int i = 0; i < rows; ++i) {
      const double* row = f + i * cols;
      for (int j = 0; j + 1 < cols; ++j)
        var_t = std::max(var_t, std::abs(row[j + 1] - row[j]));
    }
    double* high = n + kSlot;
    double* dn = n + SurfaceScratch::kGridCapacity;  // this box's own D (rational patches)
    double* high_d = high + SurfaceScratch::kGridCapacity;
    SurfaceScratch::Box lo = b, hi = b;
    lo.depth = hi.depth = b.depth + 1;
    if (var_s >= var_t) {
      split_rows(n, high, rows, cols);
      if (pp.rational) split_rows(dn, high_d, rows, cols);
      lo.s1 = hi.s0 = 0.5 * (b.s0 + b.s1);
    } else {
      split_cols(n, high, rows, cols);
      if (pp.rational) split_cols(dn, high_d, rows, cols);
      lo.t1 = hi.t0 = 0.5 * (b.t0 + b.t1);
    }
    const CoefficientRange lo_range = coefficient_range(n, d_of(n), count, pp.rational);
    const CoefficientRange hi_range = coefficient_range(high, d_of(high), count, pp.rational);
    lo.lower = lo_range.lo;
    lo.upper = lo_range.hi;
    lo.arg = lo_range.arg;
    hi.lower = hi_range.lo;
    hi.upper = hi_range.hi;
    hi.arg = hi_range.arg;
    if constexpr (kTrim) {
      if (b.straddling) {
        // Children of a straddling box: classified on their parent-(u, v) boxes; one proven
        // outside holds no face point and is dropped, one proven inside runs untrimmed.
        auto classify = [&](SurfaceScratch::Box& c) {
          const ParamInterval& pu = pp.patch.param_u;
          const ParamInterval& pv = pp.patch.param_v;
          const RegionClass k = region->classify(pu.to_parent(c.s0), pu.to_parent(c.s1),
                                                 pv.to_parent(c.t0), pv.to_parent(c.t1));
          c.straddling = k == RegionClass::boundary;
          return k != RegionClass::outside;
        };
        const bool keep_lo = classify(lo), keep_hi = classify(hi);
        if (!keep_lo || !keep_hi) {
          st.region_drops += int(!keep_lo) + int(!keep_hi);
          if (keep_hi) {
            // The survivor's coefficients go to this box's slot.
            std::copy(high, high + count, n);
            if (pp.rational) std::copy(high_d, high_d + count, dn);
            sc.boxes[top++] = hi;
          } else if (keep_lo) {
            sc.boxes[top++] = lo;
          }
          continue;
        }
      }
    }
    // Depth first, the more promising half on top (it shrinks alpha soonest).
    if (lo.lower < hi.lower) {
      std::swap_ranges(n, n + count, high);
      if (pp.rational) std::swap_ranges(dn, dn + count, high_d);
      std::swap(lo, hi);
    }
    sc.boxes[top++] = lo;
    sc.boxes[top++] = hi;
  }
}

}  // namespace

namespace {

template <bool kTrim>
[[gnu::always_inline]] inline bool clip_patch(const PreparedPatch& pp, const Vec3& p,
                                              SurfaceHit& best, SurfaceScratch& scratch,
                                              SurfaceProjectionStats* stats, double guess_s,
                                              double guess_t, const TrimRegion* region) {
  if (!p.allFinite()) return false;  // NaN would defeat every elimination test
  SurfaceProjectionStats local;
  const double reach = pp.sphere.radius + (p - pp.origin).norm();
  Clipper<kTrim> clip{pp, p, scratch, local, best.distance_sq,
                      // Each coefficient is G - 2 q.E + |q|^2 D with terms up to reach^2 D; de
                      // Casteljau is a convex combination, so the error stays a small multiple of
                      // eps reach^2.
                      1e-14 * reach * reach, 1e-11 * pp.sphere.radius};
  clip.guess_s = guess_s;
  clip.guess_t = guess_t;
  if constexpr (kTrim) clip.region = region;
  ++local.patches_visited;
  clip.run();
  bool improved = false;
  // A best candidate known only as a corner coefficient that does not beat the caller's best
  // needs no polishing: every box of the patch was eliminated against alpha <= that best or
  // finished by Newton, so the patch holds nothing closer (up to the accepted 1e-11 R).
  const bool worth_polishing = clip.best_exact || clip.best_value < best.distance_sq;
  if (std::isfinite(clip.best_value) && worth_polishing) {
    // A candidate known only through coefficients (a corner value) is polished on the geometry
    // over the whole patch (descent only: it can only improve). Newton results already are.
    double s = clip.best_s, t = clip.best_t;
    Vec3 foot = clip.best_foot;
    Vec3 normal = clip.best_normal;
    double value = clip.best_value;
    if (!clip.best_exact) {
      value = newton_on_patch(pp.patch, p, 0.0, 1.0, 0.0, 1.0, s, t, foot, &local, &normal);
      if constexpr (kTrim) {
        // The descent may leave the face: then the corner itself (in the region, it was
        // offered) is the candidate, evaluated on the geometry (a zero-size Newton box).
        if (!region->contains(pp.patch.param_u.to_parent(s), pp.patch.param_v.to_parent(t))) {
          s = clip.best_s;
          t = clip.best_t;
          value = newton_on_patch(pp.patch, p, s, s, t, t, s, t, foot, &local, &normal);
        }
      }
    }
    if (value < best.distance_sq) {
      best.u = pp.patch.param_u.to_parent(s);
      best.v = pp.patch.param_v.to_parent(t);
      best.distance_sq = value;
      best.foot = foot;
      best.s = s;
      best.t = t;
      best.normal = normal;
      improved = true;
    }
  }
  if (stats) stats->add(local);
  return improved;
}

}  // namespace

// Here, not beside the scratch: inlined into project_onto_patch (once per patch visit).
void SurfaceProjectionStats::add(const SurfaceProjectionStats& o) {
  subdivisions += o.subdivisions;
  newton_iterations += o.newton_iterations;
  depth_limit_hits += o.depth_limit_hits;
  patches_visited += o.patches_visited;
  eliminations += o.eliminations;
  convex_terminations += o.convex_terminations;
  boundary_reductions += o.boundary_reductions;
  resolution_terminations += o.resolution_terminations;
  region_drops += o.region_drops;
  region_rejections += o.region_rejections;
}

NURBSREG_HOT_CLONES
bool project_onto_patch(const PreparedPatch& pp, const Vec3& p, SurfaceHit& best,
                        SurfaceScratch& scratch, SurfaceProjectionStats* stats, double guess_s,
                        double guess_t, const TrimRegion* region) {
  if (region != nullptr) {
    return clip_patch<true>(pp, p, best, scratch, stats, guess_s, guess_t, region);
  }
  return clip_patch<false>(pp, p, best, scratch, stats, guess_s, guess_t, nullptr);
}

bool squared_distance_convex(const PreparedPatch& pp, const Vec3& p, SurfaceScratch& scratch) {
  if (!p.allFinite()) return false;
  double* n = scratch.grids.data();
  pp.numerator(p, n);
  if (!pp.rational) return convex_polynomial(n, pp.rows, pp.cols);
  const CoefficientRange range = coefficient_range(n, pp.d.data(), pp.rows * pp.cols, true);
  return rational_box_test(n, pp.d.data(), pp.rows, pp.cols, range.lo, range.hi) == kConvexBox;
}

}  // namespace nurbsreg::engine
