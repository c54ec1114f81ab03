#pragma once
// Internal: Bézier bounds on the derivatives of the squared distance F on a box of a patch, and
// the two proofs built on them: strict convexity (the clipping's termination test, the warm
// certificates' radius) and a proven sign of F_s or F_t (the monotone edge test).

#include <algorithm>
#include <cmath>
#include <limits>

#include "nurbsreg/engine/surface_projection.hpp"
#include "platform/cpu_dispatch.hpp"
#include "platform/vector_lanes.hpp"

namespace nurbsreg::engine {
namespace {

// Ranges of the Bernstein coefficients of the first and second partial derivatives of a scalar
// tensor Bernstein polynomial of degree (rows - 1, cols - 1) on the local box (differenced
// coefficients; by the convex hull property each derivative lies in its range).
struct DerivativeRanges {
  Iv v, s, t, ss, st, tt;
};

// One tight loop per derivative (no per-element branches: on the grids of high-degree patches,
// up to 41 x 41 for degree 20 in F, the one loop with six guarded updates was a fifth of the time
// on linkrods.step). Every range takes its elements in the same row-major order as before and
// scales after the extremes: multiplying by a positive constant is monotone under rounding, so
// the ranges are bit for bit those of the scaled elements.
[[maybe_unused]] DerivativeRanges derivative_ranges(const double* a, int rows, int cols) {
  const double inf = std::numeric_limits<double>::infinity();
  DerivativeRanges r{{inf, -inf}, {inf, -inf}, {inf, -inf}, {inf, -inf}, {inf, -inf}, {inf, -inf}};
  const auto grow = [](double& lo, double& hi, double x) {
    lo = std::min(lo, x);
    hi = std::max(hi, x);
  };
  const int m = rows - 1, n = cols - 1;
  for (int k = 0; k < rows * cols; ++k)
    grow(r.v.lo, r.v.hi, a[k]);
  for (int i = 0; i + 1 < rows; ++i) {
    const double* r0 = a + i * cols;
    const double* r1 = r0 + cols;
    for (int j = 0; j < cols; ++j)
      grow(r.s.lo, r.s.hi, r1[j] - r0[j]);
    for (int j = 0; j + 1 < cols; ++j)
      grow(r.st.lo, r.st.hi, r1[j + 1] - r1[j] - r0[j + 1] + r0[j]);
  }
  for (int i = 0; i < rows; ++i) {
    const double* row = a + i * cols;
    for (int j = 0; j + 1 < cols; ++j)
      grow(r.t.lo, r.t.hi, row[j + 1] - row[j]);
    for (int j = 0; j + 2 < cols; ++j)
      grow(r.tt.lo, r.tt.hi, row[j + 2] - 2.0 * row[j + 1] + row[j]);
  }
  for (int i = 0; i + 2 < rows; ++i) {
    const double* r0 = a + i * cols;
    const double* r1 = r0 + cols;
    const double* r2 = r1 + cols;
    for (int j = 0; j < cols; ++j)
      grow(r.ss.lo, r.ss.hi, r2[j] - 2.0 * r1[j] + r0[j]);
  }
  const auto scale = [](Iv& iv, double k) {
    if (iv.lo > iv.hi) {
      iv = {0.0, 0.0};  // degree 0 (or 1 for a second derivative): identically zero
    } else {
      iv = {k * iv.lo, k * iv.hi};
    }
  };
  scale(r.s, m);
  scale(r.t, n);
  scale(r.ss, double(m) * (m - 1));
  scale(r.tt, double(n) * (n - 1));
  scale(r.st, double(m) * n);
  return r;
}

// Bounds used by the termination and edge tests, from Bézier bounds (differenced coefficients).
// Polynomial patch (D == 1): the ranges of F's own first and second derivatives.
// Rational patch, F = N / D: bounding F's derivatives through the quotient rule by interval
// arithmetic works but is loose (F_s D_s and F D_ss terms). We use instead the polynomials
//   G_c = N - c D,   c in [c_lo, c_hi] = [min f_ij, max f_ij] (contains F's range on the box),
// whose coefficients are affine in c, so the union of the ranges at c_lo and c_hi bounds them for
// every c. The returned ranges are those of G_c's derivatives over all such c. Why they suffice:
//  - sign of F_s: at any x, F_s(x) = (G_c)_s(x) / D(x) with c = F(x); so (G_c)_s > 0 for all c
//    proves F_s > 0 on the box (the edge test).
//  - convexity: if every G_c is strictly convex on the box, F is strictly quasi-convex there and a
//    KKT point x* of F on the box is its global minimiser: grad F(x*) = grad G_m(x*) / D with
//    m = F(x*), so x* is a KKT point of the convex G_m, hence G_m >= G_m(x*) = 0 on the box,
//    i.e. F >= m. A box-constrained Newton (descent to a KKT point) therefore finds the minimum.
// For D == 1 both readings coincide.
struct FDerivatives {
  Iv s, t, ss, tt, st;
};

[[maybe_unused]] Iv hull(Iv a, Iv b) {
  return {std::min(a.lo, b.lo), std::max(a.hi, b.hi)};
}

[[maybe_unused]] FDerivatives f_derivatives(const double* n_grid, const double* d_grid, int rows,
                                            int cols, bool rational, Iv f_range) {
  if (!rational) {
    const DerivativeRanges n = derivative_ranges(n_grid, rows, cols);
    return {n.s, n.t, n.ss, n.tt, n.st};
  }
  double shifted[SurfaceScratch::kGridCapacity];
  FDerivatives r{};
  for (int end = 0; end < 2; ++end) {
    const double c = end == 0 ? f_range.lo : f_range.hi;
    for (int k = 0; k < rows * cols; ++k)
      shifted[k] = n_grid[k] - c * d_grid[k];
    const DerivativeRanges g = derivative_ranges(shifted, rows, cols);
    if (end == 0) {
      r = {g.s, g.t, g.ss, g.tt, g.st};
    } else {
      r = {hull(r.s, g.s), hull(r.t, g.t), hull(r.ss, g.ss), hull(r.tt, g.tt), hull(r.st, g.st)};
    }
  }
  return r;
}

// Termination test (DESIGN.md): min F_ss > 0, min F_tt > 0 and min F_ss min F_tt > max F_st^2
// imply a positive definite Hessian on the whole box (of F, or of every G_c for a rational patch),
// hence a unique minimiser on the box that a descent method (box-constrained Newton) finds.
[[maybe_unused]] bool convex(const FDerivatives& f) {
  // A relative margin keeps rounding in the differences from faking convexity.
  const double margin = 1e-12 * (std::abs(f.ss.hi) + std::abs(f.tt.hi) + std::abs(f.st.hi));
  const double a = f.ss.lo - margin, b = f.tt.lo - margin;
  const double c = std::max(std::abs(f.st.lo), std::abs(f.st.hi)) + margin;
  return a > 0.0 && b > 0.0 && a * b > c * c;
}

// Monotonicity edge test, valid for rational patches too (see f_derivatives for the sign of F_s
// through G_c): if F_s > 0 on the whole box, every
// point (s, t) has F(s, t) > F(s0, t), so the box's minimum lies on its edge s = s0 (and so on).
// This replaces seed 001's Theorem 2 where that does not hold (rational F). Returns the edge as in
// boundary_edge, or -1.
[[maybe_unused]] int monotone_edge(const FDerivatives& f) {
  const double margin_s = 1e-12 * std::max(std::abs(f.s.lo), std::abs(f.s.hi));
  const double margin_t = 1e-12 * std::max(std::abs(f.t.lo), std::abs(f.t.hi));
  if (f.s.lo > margin_s) return 0;
  if (f.s.hi < -margin_s) return 1;
  if (f.t.lo > margin_t) return 2;
  if (f.t.hi < -margin_t) return 3;
  return -1;
}

// second_derivative_ranges for a fixed grid (R, C): the same differences (element-wise, in the
// same order of operations) and the same minima and maxima (they do not depend on the order they
// are taken in), with the columns of a row in vector lanes (vector_lanes below) and one
// horizontal pass per derivative.
template <int R, int C>
[[gnu::always_inline]] inline bool second_derivative_ranges_fixed(const double* a, FDerivatives& f);

// Polynomial F (D == 1) only: the ranges of F's own second derivatives on the box (f.ss, f.tt,
// f.st; the first-derivative ranges are left alone), computed in one pass per derivative with an
// exit as soon as min F_ss <= 0 or min F_tt <= 0 (false): `convex` then fails whatever the margin
// is, and so does any widening of the ranges (grid_convexity_radius). The same values as
// derivative_ranges. Inlined: it then runs in its callers' own (possibly AVX2) code.
[[gnu::always_inline]] inline bool second_derivative_ranges(const double* a, int rows, int cols,
                                                            FDerivatives& f) {
  if (rows < 3 || cols < 3) return false;  // F_ss or F_tt identically zero
  // The grids of bicubic and biquadratic patches (and their mixes) get unrolled code.
  if (rows == 7 && cols == 7) return second_derivative_ranges_fixed<7, 7>(a, f);
  if (rows == 5 && cols == 5) return second_derivative_ranges_fixed<5, 5>(a, f);
  if (rows == 5 && cols == 7) return second_derivative_ranges_fixed<5, 7>(a, f);
  if (rows == 7 && cols == 5) return second_derivative_ranges_fixed<7, 5>(a, f);
  // Any other grid (the IEA blade's degree-(3, 8) strips: 7 x 17) in vector lanes, two vectors
  // at a time into two slots: four independent chains of minima and maxima where one value at a
  // time made two, each waiting on the one before (min and max are exact: the same ranges).
  using Pair = SlotRange<2 * kLanes>;
  constexpr int kStep = 2 * kLanes;
  // F_ss: one flat pass, the rows being contiguous.
  Pair ss;
  const int ss_count = (rows - 2) * cols;
  int k = 0;
  for (; k + kStep <= ss_count; k += kStep) {
    for (int v = 0; v < 2; ++v) {
      const double* x = a + k + v * kLanes;
      ss.add(v, load_lanes(x + 2 * cols) - 2.0 * load_lanes(x + cols) + load_lanes(x));
    }
  }
  Iv ss_range = ss.reduce();
  for (; k < ss_count; ++k) {
    const double x = a[k + 2 * cols] - 2.0 * a[k + cols] + a[k];
    ss_range.lo = std::min(ss_range.lo, x);
    ss_range.hi = std::max(ss_range.hi, x);
  }
  if (!(ss_range.lo > 0.0)) return false;
  // F_tt: along each row, cols - 2 differences.
  Pair tt;
  Iv tt_rest{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (int i = 0; i < rows; ++i) {
    const double* r = a + i * cols;
    int j = 0;
    for (; j + kStep + 2 <= cols; j += kStep) {
      for (int v = 0; v < 2; ++v) {
        const double* x = r + j + v * kLanes;
        tt.add(v, load_lanes(x + 2) - 2.0 * load_lanes(x + 1) + load_lanes(x));
      }
    }
    for (; j + 2 < cols; ++j) {
      const double x = r[j + 2] - 2.0 * r[j + 1] + r[j];
      tt_rest.lo = std::min(tt_rest.lo, x);
      tt_rest.hi = std::max(tt_rest.hi, x);
    }
  }
  const Iv tt_lanes = tt.reduce();
  const Iv tt_range{std::min(tt_lanes.lo, tt_rest.lo), std::max(tt_lanes.hi, tt_rest.hi)};
  if (!(tt_range.lo > 0.0)) return false;
  // F_st: mixed differences, (rows - 1) x (cols - 1).
  Pair st;
  Iv st_rest{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (int i = 0; i + 1 < rows; ++i) {
    const double* r0 = a + i * cols;
    const double* r1 = r0 + cols;
    int j = 0;
    for (; j + kStep + 1 <= cols; j += kStep) {
      for (int v = 0; v < 2; ++v) {
        const int c = j + v * kLanes;
        st.add(v, load_lanes(r1 + c + 1) - load_lanes(r1 + c) - load_lanes(r0 + c + 1) +
                      load_lanes(r0 + c));
      }
    }
    for (; j + 1 < cols; ++j) {
      const double x = r1[j + 1] - r1[j] - r0[j + 1] + r0[j];
      st_rest.lo = std::min(st_rest.lo, x);
      st_rest.hi = std::max(st_rest.hi, x);
    }
  }
  const Iv st_lanes = st.reduce();
  const double ss_lo = ss_range.lo, ss_hi = ss_range.hi, tt_lo = tt_range.lo, tt_hi = tt_range.hi;
  const double st_lo = std::min(st_lanes.lo, st_rest.lo), st_hi = std::max(st_lanes.hi, st_rest.hi);
  // The same scaling as derivative_ranges.
  const int m = rows - 1, n = cols - 1;
  const double ks = double(m) * (m - 1), kt = double(n) * (n - 1), kst = double(m) * n;
  f.ss = {ks * ss_lo, ks * ss_hi};
  f.tt = {kt * tt_lo, kt * tt_hi};
  f.st = {kst * st_lo, kst * st_hi};
  return true;
}

template <int R, int C>
[[gnu::always_inline]] inline bool second_derivative_ranges_fixed(const double* a,
                                                                  FDerivatives& f) {
  static_assert(R >= 3 && C >= 3);
  constexpr int m = R - 1, n = C - 1;
  // F_ss: second differences down the columns, all C columns.
  SlotRange<C> ss;
  for (int i = 0; i + 2 < R; ++i) {
    const double* r0 = a + i * C;
    const double* r1 = r0 + C;
    const double* r2 = r1 + C;
    for (int v = 0; v < SlotRange<C>::kVec; ++v) {
      const int j = v * kLanes;
      ss.add(v, load_lanes(r2 + j) - 2.0 * load_lanes(r1 + j) + load_lanes(r0 + j));
    }
    for (int k = 0; k < SlotRange<C>::kRest; ++k) {
      const int j = SlotRange<C>::kVec * kLanes + k;
      ss.add_scalar(k, r2[j] - 2.0 * r1[j] + r0[j]);
    }
  }
  const Iv ss_range = ss.reduce();
  if (!(ss_range.lo > 0.0)) return false;
  // F_tt: second differences along the rows, C - 2 per row.
  SlotRange<C - 2> tt;
  for (int i = 0; i < R; ++i) {
    const double* r = a + i * C;
    for (int v = 0; v < SlotRange<C - 2>::kVec; ++v) {
      const int j = v * kLanes;
      tt.add(v, load_lanes(r + j + 2) - 2.0 * load_lanes(r + j + 1) + load_lanes(r + j));
    }
    for (int k = 0; k < SlotRange<C - 2>::kRest; ++k) {
      const int j = SlotRange<C - 2>::kVec * kLanes + k;
      tt.add_scalar(k, r[j + 2] - 2.0 * r[j + 1] + r[j]);
    }
  }
  const Iv tt_range = tt.reduce();
  if (!(tt_range.lo > 0.0)) return false;
  // F_st: mixed differences, (R - 1) x (C - 1).
  SlotRange<C - 1> st;
  for (int i = 0; i + 1 < R; ++i) {
    const double* r0 = a + i * C;
    const double* r1 = r0 + C;
    for (int v = 0; v < SlotRange<C - 1>::kVec; ++v) {
      const int j = v * kLanes;
      st.add(v, load_lanes(r1 + j + 1) - load_lanes(r1 + j) - load_lanes(r0 + j + 1) +
                    load_lanes(r0 + j));
    }
    for (int k = 0; k < SlotRange<C - 1>::kRest; ++k) {
      const int j = SlotRange<C - 1>::kVec * kLanes + k;
      st.add_scalar(k, r1[j + 1] - r1[j] - r0[j + 1] + r0[j]);
    }
  }
  const Iv st_range = st.reduce();
  // The same scaling as derivative_ranges.
  const double ks = double(m) * (m - 1), kt = double(n) * (n - 1), kst = double(m) * n;
  f.ss = {ks * ss_range.lo, ks * ss_range.hi};
  f.tt = {kt * tt_range.lo, kt * tt_range.hi};
  f.st = {kst * st_range.lo, kst * st_range.hi};
  return true;
}

}  // namespace

// (convex_polynomial, the clipping's test on F's own second derivatives: surface/box_tests.hpp.)

// The largest r <= r_max (bisection, rounded down) such that the convexity test holds on the
// coefficient grid `n` (F_a on some box) for every q with |q - a| <= r, given bounds on the norms
// of the box's E second differences (s, t, mixed); 0 when it fails at a itself. Polynomial
// patches only (warm certificates, proofs/warm_certificate.cpp).
double grid_convexity_radius(const double* n, int rows, int cols, double e_ss, double e_tt,
                             double e_st, double r_max);

// The same for a grid `h` whose second differences move, for a query within r of the anchor, by
// at most r lin_X + r^2 quad_X + fixed_X (X = ss, tt, st: bounds on the differences' own change,
// before the derivatives' degree factors): the rational certificates' G = N_q - m D
// (warm_certificate.cpp). 0 when the test fails at r = 0.
struct Widening {
  double lin_ss, lin_tt, lin_st, quad_ss, quad_tt, quad_st, fixed_ss, fixed_tt, fixed_st;
};
double grid_convexity_radius_widened(const double* h, int rows, int cols, const Widening& w,
                                     double r_max);

}  // namespace nurbsreg::engine
