#pragma once
// Internal: the clipping's tests on a box, computed in vector lanes: convexity and the monotone
// edge for a rational patch (rational_box_test), convexity (convex_polynomial) and the monotone
// edge alone for a polynomial one. Included by the clipping only: the AVX2 and baseline
// versions are dispatched where both are visible (function multiversioning).

#include <algorithm>
#include <cstring>
#include <limits>

#include "nurbsreg/engine/surface_projection.hpp"
#include "platform/cpu_dispatch.hpp"
#include "platform/vector_lanes.hpp"
#include "surface/derivative_bounds.hpp"

namespace nurbsreg::engine {
namespace {

// The clipping's tests on a box of a rational patch (N and D grids, rows x cols; F's range on
// the box in [f_lo, f_hi]): kConvexBox when convex(f_derivatives(n, d, rows, cols, true,
// {f_lo, f_hi})) holds, else monotone_edge of the same bounds (an edge, or -1). The same
// decisions, from the same differences in vector lanes, without the unused range of G itself,
// and only as far as the decision needs (convexity fails at the first non-positive minimum).
constexpr int kConvexBox = -2;

// Running minimum and maximum of values fed W at a time (vector lanes) or one at a time; the
// same extremes as std::min / std::max over the values in any order (a NaN is ignored). Vectors
// are loaded with memcpy and passed by reference only (a 32-byte vector by value outside AVX
// code would change the ABI).
template <int W>
struct RunningRange {
  using V = typename LanesOf<W>::type;
  static constexpr double kInf = std::numeric_limits<double>::infinity();
  V lo = V{} + kInf, hi = V{} - kInf;
  double rest_lo = kInf, rest_hi = -kInf;
  static void load(V& v, const double* x) { std::memcpy(&v, x, sizeof v); }
  void add(const V& x) {
    lo = x < lo ? x : lo;
    hi = hi < x ? x : hi;
  }
  void add(double x) {
    rest_lo = std::min(rest_lo, x);
    rest_hi = std::max(rest_hi, x);
  }
  // The range of the values so far ({inf, -inf} when none).
  Iv range() const {
    double l = rest_lo, h = rest_hi;
    for (int i = 0; i < W; ++i) {
      l = std::min(l, lo[i]);
      h = std::max(h, hi[i]);
    }
    return {l, h};
  }
  // derivative_ranges' scaling: k times the range, {0, 0} when no value came in.
  Iv scaled(double k) const {
    const Iv r = range();
    if (r.lo > r.hi) return {0.0, 0.0};
    return {k * r.lo, k * r.hi};
  }
};

// The differences of derivative_ranges, element for element (the same operations in the same
// order), of one grid `a` (rows x cols, row-major), folded into a running range. Along s the
// rows are contiguous, so s and ss are one flat pass each.
template <int W>
[[gnu::always_inline]] inline void fold_s(const double* a, int rows, int cols, RunningRange<W>& r) {
  using R = RunningRange<W>;
  const int count = (rows - 1) * cols;
  int k = 0;
  typename R::V x0, x1;
  for (; k + W <= count; k += W) {
    R::load(x0, a + k);
    R::load(x1, a + k + cols);
    r.add(x1 - x0);
  }
  for (; k < count; ++k)
    r.add(a[k + cols] - a[k]);
}
template <int W>
[[gnu::always_inline]] inline void fold_ss(const double* a, int rows, int cols,
                                           RunningRange<W>& r) {
  using R = RunningRange<W>;
  const int count = (rows - 2) * cols;
  int k = 0;
  typename R::V x0, x1, x2;
  for (; k + W <= count; k += W) {
    R::load(x0, a + k);
    R::load(x1, a + k + cols);
    R::load(x2, a + k + 2 * cols);
    r.add(x2 - 2.0 * x1 + x0);
  }
  for (; k < count; ++k)
    r.add(a[k + 2 * cols] - 2.0 * a[k + cols] + a[k]);
}
template <int W>
[[gnu::always_inline]] inline void fold_t(const double* a, int rows, int cols, RunningRange<W>& r) {
  using R = RunningRange<W>;
  for (int i = 0; i < rows; ++i) {
    const double* row = a + i * cols;
    int j = 0;
    typename R::V x0, x1;
    for (; j + W < cols; j += W) {
      R::load(x0, row + j);
      R::load(x1, row + j + 1);
      r.add(x1 - x0);
    }
    for (; j + 1 < cols; ++j)
      r.add(row[j + 1] - row[j]);
  }
}
template <int W>
[[gnu::always_inline]] inline void fold_tt(const double* a, int rows, int cols,
                                           RunningRange<W>& r) {
  using R = RunningRange<W>;
  for (int i = 0; i < rows; ++i) {
    const double* row = a + i * cols;
    int j = 0;
    typename R::V x0, x1, x2;
    for (; j + W + 1 < cols; j += W) {
      R::load(x0, row + j);
      R::load(x1, row + j + 1);
      R::load(x2, row + j + 2);
      r.add(x2 - 2.0 * x1 + x0);
    }
    for (; j + 2 < cols; ++j)
      r.add(row[j + 2] - 2.0 * row[j + 1] + row[j]);
  }
}
template <int W>
[[gnu::always_inline]] inline void fold_st(const double* a, int rows, int cols,
                                           RunningRange<W>& r) {
  using R = RunningRange<W>;
  for (int i = 0; i + 1 < rows; ++i) {
    const double* r0 = a + i * cols;
    const double* r1 = r0 + cols;
    int j = 0;
    typename R::V a00, a01, a10, a11;
    for (; j + W < cols; j += W) {
      R::load(a00, r0 + j);
      R::load(a01, r0 + j + 1);
      R::load(a10, r1 + j);
      R::load(a11, r1 + j + 1);
      r.add(a11 - a10 - a01 + a00);
    }
    for (; j + 1 < cols; ++j)
      r.add(r1[j + 1] - r1[j] - r0[j + 1] + r0[j]);
  }
}

// One derivative's range over the grids of both ends (f_derivatives: each end's range scaled,
// then their hull).
template <int W, class Fold>
[[gnu::always_inline]] inline Iv both_ends(const double* g0, const double* g1, double k,
                                           Fold fold) {
  RunningRange<W> r0, r1;
  fold(g0, r0);
  fold(g1, r1);
  return hull(r0.scaled(k), r1.scaled(k));
}

template <int W>
[[gnu::always_inline]] inline int rational_box_test_lanes(const double* n, const double* d,
                                                          int rows, int cols, double f_lo,
                                                          double f_hi) {
  using R = RunningRange<W>;
  using V = typename R::V;
  // G_c = N - c D at both ends of F's range, as f_derivatives makes them.
  double g[2][SurfaceScratch::kGridCapacity];
  const int count = rows * cols;
  for (int end = 0; end < 2; ++end) {
    const double c = end == 0 ? f_lo : f_hi;
    double* out = g[end];
    int k = 0;
    V nk, dk;
    for (; k + W <= count; k += W) {
      R::load(nk, n + k);
      R::load(dk, d + k);
      const V x = nk - c * dk;
      std::memcpy(out + k, &x, sizeof x);
    }
    for (; k < count; ++k)
      out[k] = n[k] - c * d[k];
  }
  const int m = rows - 1, q = cols - 1;
  FDerivatives f{};
  // `convex` needs min F_ss > 0 and min F_tt > 0 (less a non-negative margin): a non-positive
  // minimum decides it before the other ranges are made.
  f.ss = both_ends<W>(g[0], g[1], double(m) * (m - 1),
                      [&](const double* a, R& r) { fold_ss<W>(a, rows, cols, r); });
  if (f.ss.lo > 0.0) {
    f.tt = both_ends<W>(g[0], g[1], double(q) * (q - 1),
                        [&](const double* a, R& r) { fold_tt<W>(a, rows, cols, r); });
    if (f.tt.lo > 0.0) {
      f.st = both_ends<W>(g[0], g[1], double(m) * q,
                          [&](const double* a, R& r) { fold_st<W>(a, rows, cols, r); });
      if (convex(f)) return kConvexBox;
    }
  }
  f.s = both_ends<W>(g[0], g[1], double(m),
                     [&](const double* a, R& r) { fold_s<W>(a, rows, cols, r); });
  f.t = both_ends<W>(g[0], g[1], double(q),
                     [&](const double* a, R& r) { fold_t<W>(a, rows, cols, r); });
  return monotone_edge(f);
}

// convex(second_derivative_ranges(a, rows, cols)) for a polynomial F (D == 1): the bicubic and
// biquadratic grids take second_derivative_ranges' unrolled code, any other grid the same
// differences in W-wide lanes, with its exits (a row that brings min F_ss or min F_tt to zero
// or below fails the test) and the same ranges when it gets to the end.
template <int W>
[[gnu::always_inline]] inline bool convex_polynomial_lanes(const double* a, int rows, int cols) {
  FDerivatives f{};
  if (rows < 3 || cols < 3) return false;  // F_ss or F_tt identically zero
  if ((rows == 7 || rows == 5) && (cols == 7 || cols == 5)) {
    return second_derivative_ranges(a, rows, cols, f) && convex(f);
  }
  RunningRange<W> ss, tt, st;
  for (int i = 0; i + 2 < rows; ++i) {
    fold_ss<W>(a + i * cols, 3, cols, ss);
    if (!(ss.range().lo > 0.0)) return false;
  }
  for (int i = 0; i < rows; ++i) {
    fold_tt<W>(a + i * cols, 1, cols, tt);
    if (!(tt.range().lo > 0.0)) return false;
  }
  fold_st<W>(a, rows, cols, st);
  const Iv ss_range = ss.range(), tt_range = tt.range(), st_range = st.range();
  // The same scaling as derivative_ranges.
  const int m = rows - 1, n = cols - 1;
  const double ks = double(m) * (m - 1), kt = double(n) * (n - 1), kst = double(m) * n;
  f.ss = {ks * ss_range.lo, ks * ss_range.hi};
  f.tt = {kt * tt_range.lo, kt * tt_range.hi};
  f.st = {kst * st_range.lo, kst * st_range.hi};
  return convex(f);
}

#if NURBSREG_HOT_VERSIONS
NURBSREG_TARGET_V3
[[maybe_unused]] bool convex_polynomial(const double* a, int rows, int cols) {
  return convex_polynomial_lanes<4>(a, rows, cols);
}
NURBSREG_TARGET_DEFAULT
#endif
[[maybe_unused]] bool convex_polynomial(const double* a, int rows, int cols) {
  return convex_polynomial_lanes<kLanes>(a, rows, cols);
}

#if NURBSREG_HOT_VERSIONS
// Two versions instead of NURBSREG_HOT_CLONES: the AVX2 one takes four differences per vector
// (kLanes is 2 in a portable build, also inside a clone). The same values either way.
NURBSREG_TARGET_V3
[[maybe_unused]] int rational_box_test(const double* n, const double* d, int rows, int cols,
                                       double f_lo, double f_hi) {
  return rational_box_test_lanes<4>(n, d, rows, cols, f_lo, f_hi);
}
NURBSREG_TARGET_DEFAULT
#endif
[[maybe_unused]] int rational_box_test(const double* n, const double* d, int rows, int cols,
                                       double f_lo, double f_hi) {
  return rational_box_test_lanes<kLanes>(n, d, rows, cols, f_lo, f_hi);
}

// monotone_edge(f_derivatives(a, a, rows, cols, false, ...)) for a polynomial F (D == 1): only
// the first-derivative ranges it reads. Inlined into the (dispatched) clipping.
[[gnu::always_inline]] inline int polynomial_monotone_edge(const double* a, int rows, int cols) {
  RunningRange<kLanes> s, t;
  fold_s<kLanes>(a, rows, cols, s);
  fold_t<kLanes>(a, rows, cols, t);
  FDerivatives f{};
  f.s = s.scaled(rows - 1);
  f.t = t.scaled(cols - 1);
  return monotone_edge(f);
}
}  // namespace
}  // namespace nurbsreg::engine
