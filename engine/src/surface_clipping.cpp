// Spherical clipping for rational Bézier patches (seed paper 001, extended to NURBS), the cached
// squared-distance coefficients (DESIGN.md "Projection: surfaces") and the box-constrained Newton
// on the surface geometry shared by both strategies.

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>

#include "binomial_table.hpp"
#include "cpu_dispatch.hpp"
#include "nurbsreg/engine/surface_projection.hpp"
#include "nurbsreg/engine/trim_region.hpp"
#include "warm_certificate.hpp"

namespace nurbsreg::engine {
namespace {

constexpr int kMaxGridSide = 2 * kMaxDegree + 1;

NURBSREG_HOT_CLONES
double newton_core(const BezierPatch& patch, const Vec3& p, double s0, double s1, double t0,
                   double t1, double& s, double& t, Vec3& foot, SurfaceProjectionStats* stats,
                   Vec3* normal, double abort_at, bool* converged = nullptr,
                   double settled_step = 1e-15);

double binomial(int n, int k) {
  double r = 1.0;
  for (int i = 1; i <= k; ++i)
    r = r * (n - k + i) / i;
  return r;
}

// A closed range [lo, hi]. Rounding is covered by the relative margins of the tests using it.
struct Iv {
  double lo, hi;
};

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
DerivativeRanges derivative_ranges(const double* a, int rows, int cols) {
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

Iv hull(Iv a, Iv b) {
  return {std::min(a.lo, b.lo), std::max(a.hi, b.hi)};
}

FDerivatives f_derivatives(const double* n_grid, const double* d_grid, int rows, int cols,
                           bool rational, Iv f_range) {
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
bool convex(const FDerivatives& f) {
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
int monotone_edge(const FDerivatives& f) {
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
  double ss_lo = std::numeric_limits<double>::infinity(), ss_hi = -ss_lo;
  for (int i = 0; i + 2 < rows; ++i) {
    const double* r0 = a + i * cols;
    const double* r1 = r0 + cols;
    const double* r2 = r1 + cols;
    for (int j = 0; j < cols; ++j) {
      const double x = r2[j] - 2.0 * r1[j] + r0[j];
      ss_lo = std::min(ss_lo, x);
      ss_hi = std::max(ss_hi, x);
    }
    if (!(ss_lo > 0.0)) return false;
  }
  double tt_lo = std::numeric_limits<double>::infinity(), tt_hi = -tt_lo;
  for (int i = 0; i < rows; ++i) {
    const double* r = a + i * cols;
    for (int j = 0; j + 2 < cols; ++j) {
      const double x = r[j + 2] - 2.0 * r[j + 1] + r[j];
      tt_lo = std::min(tt_lo, x);
      tt_hi = std::max(tt_hi, x);
    }
    if (!(tt_lo > 0.0)) return false;
  }
  double st_lo = std::numeric_limits<double>::infinity(), st_hi = -st_lo;
  for (int i = 0; i + 1 < rows; ++i) {
    const double* r0 = a + i * cols;
    const double* r1 = r0 + cols;
    for (int j = 0; j + 1 < cols; ++j) {
      const double x = r1[j + 1] - r1[j] - r0[j + 1] + r0[j];
      st_lo = std::min(st_lo, x);
      st_hi = std::max(st_hi, x);
    }
  }
  // The same scaling as derivative_ranges.
  const int m = rows - 1, n = cols - 1;
  const double ks = double(m) * (m - 1), kt = double(n) * (n - 1), kst = double(m) * n;
  f.ss = {ks * ss_lo, ks * ss_hi};
  f.tt = {kt * tt_lo, kt * tt_hi};
  f.st = {kst * st_lo, kst * st_hi};
  return true;
}

// Polynomial F (D == 1) only: the termination test of `convex` on F's own second derivatives,
// with an exit as soon as a bound shows it fails. Same result as convex(f_derivatives(...)) for a
// polynomial patch; the first-derivative ranges are not needed there (monotone_edge is used for
// rational patches only).
NURBSREG_HOT_CLONES
bool convex_polynomial(const double* a, int rows, int cols) {
  FDerivatives f{};
  return second_derivative_ranges(a, rows, cols, f) && convex(f);
}

constexpr BinomialTable<kMaxDegree> kBinomial;
// Up to the degree of the squared distance along a boundary curve (bernstein_minimiser).
constexpr BinomialTable<2 * kMaxDegree> kWideBinomial;

// Bernstein values and first and second derivatives of degree n at t in [0, 1]:
// B_i^m = C(m, i) t^i (1 - t)^(m - i) for m = n, n - 1, n - 2 from one table of powers (all terms
// positive: no cancellation), then dB_i^n/dt = n (B_{i-1}^{n-1} - B_i^{n-1}) and the second
// difference for d2 (The NURBS Book eq. 1.9). Only entries 0..n are written.
void bernstein_012(int n, double t, double* b0, double* b1, double* b2) {
  double tp[kMaxDegree + 1], up[kMaxDegree + 1];
  const double u = 1.0 - t;
  tp[0] = up[0] = 1.0;
  for (int k = 1; k <= n; ++k) {
    tp[k] = tp[k - 1] * t;
    up[k] = up[k - 1] * u;
  }
  for (int i = 0; i <= n; ++i)
    b0[i] = kBinomial.c[n][i] * tp[i] * up[n - i];
  if (n < 1) {
    b1[0] = b2[0] = 0.0;
    return;
  }
  // l1[i] = B_i^{n-1}, with l1[-1] = l1[n] = 0.
  double l1[kMaxDegree + 2];
  l1[0] = 0.0;
  for (int i = 0; i <= n - 1; ++i)
    l1[i + 1] = kBinomial.c[n - 1][i] * tp[i] * up[n - 1 - i];
  l1[n + 1] = 0.0;
  for (int i = 0; i <= n; ++i)
    b1[i] = n * (l1[i] - l1[i + 1]);
  if (n < 2) {
    b2[0] = b2[1] = 0.0;
    return;
  }
  // l2[i + 2] = B_i^{n-2}, zero-padded by two on each side.
  double l2[kMaxDegree + 3];
  l2[0] = l2[1] = 0.0;
  for (int i = 0; i <= n - 2; ++i)
    l2[i + 2] = kBinomial.c[n - 2][i] * tp[i] * up[n - 2 - i];
  l2[n + 1] = l2[n + 2] = 0.0;
  const double nn = double(n) * (n - 1);
  for (int i = 0; i <= n; ++i)
    b2[i] = nn * (l2[i] - 2.0 * l2[i + 1] + l2[i + 2]);
}

// S, S_s, S_t, S_ss, S_st, S_tt of a rational Bézier patch at local (s, t): homogeneous tensor
// sums, then the quotient rule (The NURBS Book eq. 4.20). The same formulas as
// BezierPatch::derivatives with one basis pass per direction and no zero-filled storage: the
// Newton iteration's inner cost.
// Every weight exactly 1 (a polynomial patch, as most CAD surfaces' are): the homogeneous sums are
// then the derivatives themselves, and the quotient rule (a division and ~50 operations, 9% of a
// warm frame's time) would only divide by sums of the Bernstein values that rounding keeps
// near 1 and 0.
[[gnu::always_inline]] inline bool unit_weights(const double* cw, int count) {
  bool unit = true;
  for (int k = 0; k < count; ++k)
    unit &= cw[4 * k + 3] == 1.0;
  return unit;
}

// The quotient rule from the six homogeneous sums a_kl = d^(k+l) A / ds^k dt^l (A = Σ B B P^w).
void rational_from_homogeneous(const Vec4& a00, const Vec4& a10, const Vec4& a01, const Vec4& a20,
                               const Vec4& a11, const Vec4& a02, Vec3* out) {
  const double inv_w = 1.0 / a00[3];
  const Vec3 x = a00.head<3>() * inv_w;
  const Vec3 xs = (a10.head<3>() - a10[3] * x) * inv_w;
  const Vec3 xt = (a01.head<3>() - a01[3] * x) * inv_w;
  out[0] = x;
  out[1] = xs;
  out[2] = xt;
  out[3] = (a20.head<3>() - 2.0 * a10[3] * xs - a20[3] * x) * inv_w;
  out[4] = (a11.head<3>() - a10[3] * xt - a01[3] * xs - a11[3] * x) * inv_w;
  out[5] = (a02.head<3>() - 2.0 * a01[3] * xt - a02[3] * x) * inv_w;
}

// Fixed degree N: Bernstein values and derivatives with compile-time loop bounds (unrolled).
template <int N>
[[gnu::always_inline]] inline void bernstein_012_fixed(double t, double* b0, double* b1,
                                                       double* b2) {
  static_assert(N >= 2 && N <= kMaxDegree);
  const double u = 1.0 - t;
  double tp[N + 1], up[N + 1];
  tp[0] = up[0] = 1.0;
  for (int k = 1; k <= N; ++k) {
    tp[k] = tp[k - 1] * t;
    up[k] = up[k - 1] * u;
  }
  for (int i = 0; i <= N; ++i)
    b0[i] = kBinomial.c[N][i] * tp[i] * up[N - i];
  double l1[N + 2];
  l1[0] = l1[N + 1] = 0.0;
  for (int i = 0; i <= N - 1; ++i)
    l1[i + 1] = kBinomial.c[N - 1][i] * tp[i] * up[N - 1 - i];
  for (int i = 0; i <= N; ++i)
    b1[i] = N * (l1[i] - l1[i + 1]);
  double l2[N + 3];
  l2[0] = l2[1] = l2[N + 1] = l2[N + 2] = 0.0;
  for (int i = 0; i <= N - 2; ++i)
    l2[i + 2] = kBinomial.c[N - 2][i] * tp[i] * up[N - 2 - i];
  for (int i = 0; i <= N; ++i)
    b2[i] = double(N * (N - 1)) * (l2[i] - 2.0 * l2[i + 1] + l2[i + 2]);
}

// The tensor sums of the homogeneous patch and its partial derivatives up to order 2, from the
// Bernstein values (and their derivatives) in s and t, then the rational quotient rule. Always
// inlined: called with constant degrees (below) the loops unroll fully.
[[gnu::always_inline]] inline void tensor_derivatives(const Vec4* cw, int p, int q,
                                                      const double* const bu[3],
                                                      const double* const bv[3], Vec3* out) {
  Vec4 a00 = Vec4::Zero(), a01 = Vec4::Zero(), a02 = Vec4::Zero(), a10 = Vec4::Zero(),
       a11 = Vec4::Zero(), a20 = Vec4::Zero();
  for (int i = 0; i <= p; ++i) {
    Vec4 r0 = Vec4::Zero(), r1 = Vec4::Zero(), r2 = Vec4::Zero();
    const Vec4* row = cw + i * (q + 1);
    for (int j = 0; j <= q; ++j) {
      r0 += bv[0][j] * row[j];
      r1 += bv[1][j] * row[j];
      r2 += bv[2][j] * row[j];
    }
    a00 += bu[0][i] * r0;
    a01 += bu[0][i] * r1;
    a02 += bu[0][i] * r2;
    a10 += bu[1][i] * r0;
    a11 += bu[1][i] * r1;
    a20 += bu[2][i] * r0;
  }
  if (unit_weights(cw->data(), (p + 1) * (q + 1))) {
    out[0] = a00.head<3>();
    out[1] = a10.head<3>();
    out[2] = a01.head<3>();
    out[3] = a20.head<3>();
    out[4] = a11.head<3>();
    out[5] = a02.head<3>();
    return;
  }
  rational_from_homogeneous(a00, a10, a01, a20, a11, a02, out);
}

// The fixed-degree kernel below works on W doubles at a time (GCC vector extension: element-wise
// IEEE operations, one SSE2 or AVX register): W = 4 does the four homogeneous coordinates in one
// pass where AVX is enabled, W = 2 does (x, y) and then (z, w). Each coordinate sees exactly the
// operations of tensor_derivatives + rational_from_homogeneous in the same order (products, then
// sums from zero in index order; the same quotient-rule expressions, or the same unit-weight
// shortcut), so the results are bit-identical to them; only the schedule differs: one half of
// the accumulators at a time fits the 16 SSE registers, where the Vec4 form spilled to the
// stack.
#if defined(__AVX__)
constexpr int kLanes = 4;
#else
constexpr int kLanes = 2;
#endif
typedef double Lanes __attribute__((vector_size(sizeof(double) * kLanes)));

inline Lanes load_lanes(const double* x) {
  Lanes v;
  std::memcpy(&v, x, sizeof v);
  return v;
}

inline void store_lanes(double* x, Lanes v) {
  std::memcpy(x, &v, sizeof v);
}

// W doubles in one vector (patch_derivatives_fixed is instantiated for kLanes and, in the AVX2
// version of patch_derivatives, for 4). Loaded and stored through references and memcpy only:
// a 32-byte vector passed by value outside AVX code would change the ABI (-Wpsabi).
template <int W>
struct LanesOf;
template <>
struct LanesOf<2> {
  typedef double type __attribute__((vector_size(2 * sizeof(double))));
};
template <>
struct LanesOf<4> {
  typedef double type __attribute__((vector_size(4 * sizeof(double))));
};

// Running minimum and maximum of L values per slot, the first L - L % kLanes slots in vector
// lanes. add(j, x) folds x into slots [j, j + kLanes) (j a multiple of kLanes below the vector
// part's end); add_scalar(j, x) into slot j of the rest. min/max as std::min(acc, x) and
// std::max(acc, x) per slot (a NaN x is ignored, as there).
template <int L>
struct SlotRange {
  static constexpr int kVec = L / kLanes;
  static constexpr int kRest = L % kLanes;
  Lanes lo[kVec > 0 ? kVec : 1], hi[kVec > 0 ? kVec : 1];
  double rest_lo[kRest > 0 ? kRest : 1], rest_hi[kRest > 0 ? kRest : 1];
  SlotRange() {
    const double inf = std::numeric_limits<double>::infinity();
    Lanes plus, minus;
    for (int k = 0; k < kLanes; ++k) {
      plus[k] = inf;
      minus[k] = -inf;
    }
    for (int v = 0; v < kVec; ++v) {
      lo[v] = plus;
      hi[v] = minus;
    }
    for (int k = 0; k < kRest; ++k) {
      rest_lo[k] = inf;
      rest_hi[k] = -inf;
    }
  }
  void add(int v, Lanes x) {
    lo[v] = x < lo[v] ? x : lo[v];
    hi[v] = hi[v] < x ? x : hi[v];
  }
  void add_scalar(int k, double x) {
    rest_lo[k] = std::min(rest_lo[k], x);
    rest_hi[k] = std::max(rest_hi[k], x);
  }
  Iv reduce() const {
    double l = std::numeric_limits<double>::infinity(), h = -l;
    for (int v = 0; v < kVec; ++v) {
      for (int k = 0; k < kLanes; ++k) {
        l = std::min(l, lo[v][k]);
        h = std::max(h, hi[v][k]);
      }
    }
    for (int k = 0; k < kRest; ++k) {
      l = std::min(l, rest_lo[k]);
      h = std::max(h, rest_hi[k]);
    }
    return {l, h};
  }
};

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

// patch_derivatives for fixed degrees (P, Q): the same sums, fully unrolled by the compiler, W
// homogeneous coordinates at a time (any W gives the same values, see kLanes).
template <int P, int Q, int W>
[[gnu::always_inline]] inline void patch_derivatives_fixed(const BezierPatch& patch, double s,
                                                           double t, Vec3* out) {
  using Lanes = typename LanesOf<W>::type;
  const auto load_lanes = [](const double* x, Lanes& v) { std::memcpy(&v, x, sizeof v); };
  const auto store_lanes = [](double* x, const Lanes& v) { std::memcpy(x, &v, sizeof v); };
  double bu[3][P + 1], bv[3][Q + 1];
  bernstein_012_fixed<P>(s, bu[0], bu[1], bu[2]);
  bernstein_012_fixed<Q>(t, bv[0], bv[1], bv[2]);
  // Homogeneous sums a_kl = d^(k+l) A / ds^k dt^l, coordinate c at a_kl[c].
  alignas(32) double a00[4], a10[4], a01[4], a20[4], a11[4], a02[4];
  const double* cw = patch.cw.data()->data();  // (x, y, z, w) per control point, contiguous
  for (int h = 0; h < 4; h += W) {
    Lanes s00, s10, s01, s20, s11, s02;
    for (int i = 0; i <= P; ++i) {
      Lanes r0, r1, r2;
      {
        Lanes c;
        load_lanes(cw + 4 * (i * (Q + 1)) + h, c);
        r0 = bv[0][0] * c;
        r1 = bv[1][0] * c;
        r2 = bv[2][0] * c;
      }
      for (int j = 1; j <= Q; ++j) {
        Lanes c;
        load_lanes(cw + 4 * (i * (Q + 1) + j) + h, c);
        r0 += bv[0][j] * c;
        r1 += bv[1][j] * c;
        r2 += bv[2][j] * c;
      }
      if (i == 0) {
        s00 = bu[0][0] * r0;
        s01 = bu[0][0] * r1;
        s02 = bu[0][0] * r2;
        s10 = bu[1][0] * r0;
        s11 = bu[1][0] * r1;
        s20 = bu[2][0] * r0;
      } else {
        s00 += bu[0][i] * r0;
        s01 += bu[0][i] * r1;
        s02 += bu[0][i] * r2;
        s10 += bu[1][i] * r0;
        s11 += bu[1][i] * r1;
        s20 += bu[2][i] * r0;
      }
    }
    store_lanes(a00 + h, s00);
    store_lanes(a10 + h, s10);
    store_lanes(a01 + h, s01);
    store_lanes(a20 + h, s20);
    store_lanes(a11 + h, s11);
    store_lanes(a02 + h, s02);
  }
  if (unit_weights(cw, (P + 1) * (Q + 1))) {
    for (int c = 0; c < 3; ++c) {
      out[0][c] = a00[c];
      out[1][c] = a10[c];
      out[2][c] = a01[c];
      out[3][c] = a20[c];
      out[4][c] = a11[c];
      out[5][c] = a02[c];
    }
    return;
  }
  // rational_from_homogeneous, coordinate by coordinate, with its expressions' evaluation order.
  const double inv_w = 1.0 / a00[3];
  const double w10 = a10[3], w01 = a01[3], w20 = a20[3], w11 = a11[3], w02 = a02[3];
  for (int c = 0; c < 3; ++c) {
    const double x = a00[c] * inv_w;
    const double xs = (a10[c] - w10 * x) * inv_w;
    const double xt = (a01[c] - w01 * x) * inv_w;
    out[0][c] = x;
    out[1][c] = xs;
    out[2][c] = xt;
    out[3][c] = (a20[c] - 2.0 * w10 * xs - w20 * x) * inv_w;
    out[4][c] = (a11[c] - w10 * xt - w01 * xs - w11 * x) * inv_w;
    out[5][c] = (a02[c] - 2.0 * w01 * xt - w02 * x) * inv_w;
  }
}

template <int W>
[[gnu::always_inline]] inline void patch_derivatives_lanes(const BezierPatch& patch, double s,
                                                           double t, Vec3* out) {
  const int p = patch.degree_u, q = patch.degree_v;
  // The common degrees of CAD surfaces get unrolled code; any other takes the generic loops.
  if (p == 3 && q == 3) return patch_derivatives_fixed<3, 3, W>(patch, s, t, out);
  if (p == 2 && q == 2) return patch_derivatives_fixed<2, 2, W>(patch, s, t, out);
  if (p == 2 && q == 3) return patch_derivatives_fixed<2, 3, W>(patch, s, t, out);
  if (p == 3 && q == 2) return patch_derivatives_fixed<3, 2, W>(patch, s, t, out);
  double bu[3][kMaxDegree + 1], bv[3][kMaxDegree + 1];
  bernstein_012(p, s, bu[0], bu[1], bu[2]);
  bernstein_012(q, t, bv[0], bv[1], bv[2]);
  const double* const u_rows[3] = {bu[0], bu[1], bu[2]};
  const double* const v_rows[3] = {bv[0], bv[1], bv[2]};
  tensor_derivatives(patch.cw.data(), p, q, u_rows, v_rows, out);
}

#if NURBSREG_HOT_VERSIONS
// Two versions instead of NURBSREG_HOT_CLONES: the AVX2 one does the four homogeneous
// coordinates in one 4-wide pass (kLanes is 2 in a portable build, also inside a clone).
NURBSREG_TARGET_V3
void patch_derivatives(const BezierPatch& patch, double s, double t, Vec3* out) {
  patch_derivatives_lanes<4>(patch, s, t, out);
}
NURBSREG_TARGET_DEFAULT
#endif
void patch_derivatives(const BezierPatch& patch, double s, double t, Vec3* out) {
  patch_derivatives_lanes<kLanes>(patch, s, t, out);
}

// S, S_s and S_t only (out[0..2]): the last evaluation of a Newton that is known to stop there
// needs no second derivatives. The same sums in the same order as tensor_derivatives and
// rational_from_homogeneous (or its unit-weight shortcut), so the three values are
// bit-identical to patch_derivatives'.
template <int P, int Q>
[[gnu::always_inline]] inline void patch_first_derivatives_fixed(const BezierPatch& patch, double s,
                                                                 double t, Vec3* out) {
  double bu[3][P + 1], bv[3][Q + 1];
  bernstein_012_fixed<P>(s, bu[0], bu[1], bu[2]);
  bernstein_012_fixed<Q>(t, bv[0], bv[1], bv[2]);
  Vec4 a00 = Vec4::Zero(), a01 = Vec4::Zero(), a10 = Vec4::Zero();
  const Vec4* cw = patch.cw.data();
  for (int i = 0; i <= P; ++i) {
    Vec4 r0 = Vec4::Zero(), r1 = Vec4::Zero();
    const Vec4* row = cw + i * (Q + 1);
    for (int j = 0; j <= Q; ++j) {
      r0 += bv[0][j] * row[j];
      r1 += bv[1][j] * row[j];
    }
    a00 += bu[0][i] * r0;
    a01 += bu[0][i] * r1;
    a10 += bu[1][i] * r0;
  }
  if (unit_weights(cw->data(), (P + 1) * (Q + 1))) {
    out[0] = a00.head<3>();
    out[1] = a10.head<3>();
    out[2] = a01.head<3>();
    return;
  }
  const double inv_w = 1.0 / a00[3];
  const Vec3 x = a00.head<3>() * inv_w;
  out[0] = x;
  out[1] = (a10.head<3>() - a10[3] * x) * inv_w;
  out[2] = (a01.head<3>() - a01[3] * x) * inv_w;
}

// false when the degrees have no first-derivative kernel (the caller evaluates in full).
NURBSREG_HOT_CLONES
bool patch_first_derivatives(const BezierPatch& patch, double s, double t, Vec3* out) {
  const int p = patch.degree_u, q = patch.degree_v;
  if (p == 3 && q == 3) return patch_first_derivatives_fixed<3, 3>(patch, s, t, out), true;
  if (p == 2 && q == 2) return patch_first_derivatives_fixed<2, 2>(patch, s, t, out), true;
  if (p == 2 && q == 3) return patch_first_derivatives_fixed<2, 3>(patch, s, t, out), true;
  if (p == 3 && q == 2) return patch_first_derivatives_fixed<3, 2>(patch, s, t, out), true;
  return false;
}

// de Casteljau at 1/2 along s (rows): `low` (in place) gets [s0, mid], `high` [mid, s1].
NURBSREG_HOT_CLONES
void split_rows(double* low, double* high, int rows, int cols) {
  double work[kMaxGridSide];
  const int m = rows - 1;
  for (int j = 0; j < cols; ++j) {
    for (int i = 0; i < rows; ++i)
      work[i] = low[i * cols + j];
    high[m * cols + j] = work[m];
    for (int r = 1; r <= m; ++r) {
      for (int i = 0; i <= m - r; ++i)
        work[i] = 0.5 * (work[i] + work[i + 1]);
      low[r * cols + j] = work[0];
      high[(m - r) * cols + j] = work[m - r];
    }
  }
}

// de Casteljau at 1/2 along t of one contiguous row of `count` values.
NURBSREG_HOT_CLONES
void split_line(double* low, double* high, int count) {
  double work[kMaxGridSide];
  const int n = count - 1;
  std::memcpy(work, low, sizeof(double) * count);
  high[n] = work[n];
  for (int r = 1; r <= n; ++r) {
    for (int i = 0; i <= n - r; ++i)
      work[i] = 0.5 * (work[i] + work[i + 1]);
    low[r] = work[0];
    high[n - r] = work[n - r];
  }
}

void split_cols(double* low, double* high, int rows, int cols) {
  for (int i = 0; i < rows; ++i)
    split_line(low + i * cols, high + i * cols, cols);
}

// Smallest and largest coefficient ratio N_k / D_k and the index of the smallest, in one pass.
struct CoefficientRange {
  double lo, hi;
  int arg;
};

NURBSREG_HOT_CLONES
CoefficientRange coefficient_range(const double* n, const double* d, int count, bool rational) {
  CoefficientRange r{std::numeric_limits<double>::infinity(),
                     -std::numeric_limits<double>::infinity(), 0};
  if (!rational) {
    // The minimum and maximum only, in vector lanes (order-independent; a NaN is ignored as
    // below). The index of the minimum is wanted only where a box ends in Newton: arg = -1, and
    // first_index_of finds it then (the first index holding the minimum, as the strict test
    // below keeps).
    SlotRange<kLanes> lanes;
    int k = 0;
    for (; k + kLanes <= count; k += kLanes)
      lanes.add(0, load_lanes(n + k));
    Iv range = lanes.reduce();
    for (; k < count; ++k) {
      range.lo = std::min(range.lo, n[k]);
      range.hi = std::max(range.hi, n[k]);
    }
    r.lo = range.lo;
    r.hi = range.hi;
    r.arg = -1;
    return r;
  }
  for (int k = 0; k < count; ++k) {
    const double f = rational ? n[k] / d[k] : n[k];
    if (f < r.lo) {
      r.lo = f;
      r.arg = k;
    }
    r.hi = std::max(r.hi, f);
  }
  return r;
}

// The first index k with a[k] == value (0 if none): the arg of coefficient_range's minimum.
int first_index_of(const double* a, int count, double value) {
  for (int k = 0; k < count; ++k) {
    if (a[k] == value) return k;
  }
  return 0;
}

// Theorem 2 of seed 001 for a polynomial F: if the coefficients of one boundary row (column) are
// below every coefficient of their column (row), F attains its minimum over the box on that edge.
// Returns 0: s = s0, 1: s = s1, 2: t = t0, 3: t = t1, or -1. Not used for rational patches: the
// proof compares F with F(u0, v) through the same Bernstein weights, which a rational F (weights
// B D_ij / Σ B D) does not share, so it does not carry over.
NURBSREG_HOT_CLONES
int boundary_edge(const double* f, int rows, int cols) {
  auto row_below = [&](int r) {
    const double* edge = f + r * cols;
    for (int i = 0; i < rows; ++i) {
      for (int j = 0; j < cols; ++j) {
        if (f[i * cols + j] < edge[j]) return false;
      }
    }
    return true;
  };
  auto col_below = [&](int c) {
    for (int i = 0; i < rows; ++i) {
      const double edge = f[i * cols + c];
      for (int j = 0; j < cols; ++j) {
        if (f[i * cols + j] < edge) return false;
      }
    }
    return true;
  };
  if (row_below(0)) return 0;
  if (row_below(rows - 1)) return 1;
  if (col_below(0)) return 2;
  if (col_below(cols - 1)) return 3;
  return -1;
}

// Minimiser of a polynomial f given by its Bernstein coefficients c[0..count) on [0, 1]: a
// projected Newton on f' (its Bernstein derivative coefficients) from u, a few flops per step.
// Only a starting point for the Newton on the surface geometry (which does the real work, from
// any start): being solved on f' = 0, it is accurate to about the coefficients' rounding
// relative to f'' (linear, not square-root, in it), so the geometric Newton then needs one
// step instead of four or five. Stops where f'' <= 0 (returns the point reached), at a bound
// whose derivative points outward, and after a few iterations.
// kCount > 0: a fixed number of coefficients (unrolled loops); 0: count at run time.
template <int kCount>
[[gnu::always_inline]] inline double bernstein_minimiser_impl(const double* c, int count,
                                                              double u) {
  if constexpr (kCount > 0) count = kCount;
  const int n = count - 1;
  if (n < 2) return u;
  double d1[2 * kMaxDegree], d2[2 * kMaxDegree];
  for (int j = 0; j < n; ++j)
    d1[j] = n * (c[j + 1] - c[j]);
  for (int j = 0; j + 1 < n; ++j)
    d2[j] = double(n) * (n - 1) * (c[j + 2] - 2.0 * c[j + 1] + c[j]);
  for (int it = 0; it < 8; ++it) {
    // Bernstein sums of degree n - 1 (d1) and n - 2 (d2) at u, from the powers of u and 1 - u.
    double xp[2 * kMaxDegree + 1], yp[2 * kMaxDegree + 1];
    xp[0] = yp[0] = 1.0;
    for (int k = 1; k < n; ++k) {
      xp[k] = xp[k - 1] * u;
      yp[k] = yp[k - 1] * (1.0 - u);
    }
    double g = 0.0, h = 0.0;
    for (int j = 0; j < n; ++j)
      g += kWideBinomial.c[n - 1][j] * xp[j] * yp[n - 1 - j] * d1[j];
    for (int j = 0; j + 1 < n; ++j)
      h += kWideBinomial.c[n - 2][j] * xp[j] * yp[n - 2 - j] * d2[j];
    if (!(h > 0.0)) break;
    if ((u <= 0.0 && g >= 0.0) || (u >= 1.0 && g <= 0.0)) break;
    const double next = std::clamp(u - g / h, 0.0, 1.0);
    if (!std::isfinite(next)) break;
    const double moved = std::abs(next - u);
    u = next;
    if (moved <= 1e-15) break;
  }
  return u;
}

NURBSREG_HOT_CLONES
double bernstein_minimiser(const double* c, int count, double u) {
  if (count == 7) return bernstein_minimiser_impl<7>(c, count, u);  // bicubic
  if (count == 5) return bernstein_minimiser_impl<5>(c, count, u);  // biquadratic
  return bernstein_minimiser_impl<0>(c, count, u);
}

// The 2-D counterpart of bernstein_minimiser for a polynomial F on a box where it is proven
// convex (convex_polynomial): a projected Newton on F's own Bernstein grid a (R x C, row-major)
// from (u, v) in [0, 1]^2. F's gradient and Hessian come from the grid in a few hundred flops,
// about half a geometric Newton step (patch_derivatives plus the quotient rule), and the
// minimiser it reaches is accurate to the coefficients' rounding relative to the Hessian, so the
// Newton on the geometry that follows needs one or two steps instead of four or five. Only a
// start: stops where the Hessian is not positive definite, when no variable is free, after a
// few iterations.
template <int R, int C>
[[gnu::always_inline]] inline void bernstein_minimiser_2d(const double* a, double& u, double& v) {
  constexpr int m = R - 1, n = C - 1;
  for (int it = 0; it < 8; ++it) {
    double bu[3][R], bv[3][C];
    bernstein_012_fixed<m>(u, bu[0], bu[1], bu[2]);
    bernstein_012_fixed<n>(v, bv[0], bv[1], bv[2]);
    // Column sums first, the columns of a row in vector lanes (and the last C % kLanes as
    // scalars), then one dot product per derivative.
    constexpr int kVec = C / kLanes, kRest = C % kLanes, kSplit = kVec * kLanes;
    Lanes c0[kVec > 0 ? kVec : 1], c1[kVec > 0 ? kVec : 1], c2[kVec > 0 ? kVec : 1];
    double r0[kRest > 0 ? kRest : 1], r1[kRest > 0 ? kRest : 1], r2[kRest > 0 ? kRest : 1];
    for (int i = 0; i < R; ++i) {
      const double* row = a + i * C;
      const double w0 = bu[0][i], w1 = bu[1][i], w2 = bu[2][i];
      for (int k = 0; k < kVec; ++k) {
        const Lanes x = load_lanes(row + k * kLanes);
        c0[k] = i == 0 ? w0 * x : c0[k] + w0 * x;
        c1[k] = i == 0 ? w1 * x : c1[k] + w1 * x;
        c2[k] = i == 0 ? w2 * x : c2[k] + w2 * x;
      }
      for (int k = 0; k < kRest; ++k) {
        const double x = row[kSplit + k];
        r0[k] = i == 0 ? w0 * x : r0[k] + w0 * x;
        r1[k] = i == 0 ? w1 * x : r1[k] + w1 * x;
        r2[k] = i == 0 ? w2 * x : r2[k] + w2 * x;
      }
    }
    // The dot products in the order of the 2-lane code whatever kLanes is (lane l sums the
    // columns j = l mod 2 below 2 (C / 2), then lane 0 + lane 1 and the last column): a build
    // with kLanes = 4 (-march=native) gives the same start, hence the same results.
    double fu = 0.0, fuu = 0.0, fv = 0.0, fuv = 0.0, fvv = 0.0;
    if constexpr (kLanes == 2) {
      Lanes vu = {}, vuu = {}, vv = {}, vuv = {}, vvv = {};
      for (int k = 0; k < kVec; ++k) {
        const Lanes b0 = load_lanes(bv[0] + k * kLanes), b1 = load_lanes(bv[1] + k * kLanes);
        const Lanes b2 = load_lanes(bv[2] + k * kLanes);
        vu += b0 * c1[k];
        vuu += b0 * c2[k];
        vv += b1 * c0[k];
        vuv += b1 * c1[k];
        vvv += b2 * c0[k];
      }
      for (int l = 0; l < kLanes; ++l) {
        fu += vu[l];
        fuu += vuu[l];
        fv += vv[l];
        fuv += vuv[l];
        fvv += vvv[l];
      }
      for (int k = 0; k < kRest; ++k) {
        fu += bv[0][kSplit + k] * r1[k];
        fuu += bv[0][kSplit + k] * r2[k];
        fv += bv[1][kSplit + k] * r0[k];
        fuv += bv[1][kSplit + k] * r1[k];
        fvv += bv[2][kSplit + k] * r0[k];
      }
    } else {
      double col0[C], col1[C], col2[C];  // the column sums, in plain arrays
      for (int k = 0; k < kVec; ++k) {
        store_lanes(col0 + k * kLanes, c0[k]);
        store_lanes(col1 + k * kLanes, c1[k]);
        store_lanes(col2 + k * kLanes, c2[k]);
      }
      for (int k = 0; k < kRest; ++k) {
        col0[kSplit + k] = r0[k];
        col1[kSplit + k] = r1[k];
        col2[kSplit + k] = r2[k];
      }
      const auto dot = [](const double* b, const double* c) {
        constexpr int kPairs = C / 2;
        double lane[2] = {0.0, 0.0};
        for (int k = 0; k < kPairs; ++k) {
          for (int l = 0; l < 2; ++l)
            lane[l] += b[2 * k + l] * c[2 * k + l];
        }
        double f = 0.0;
        f += lane[0];
        f += lane[1];
        for (int j = 2 * kPairs; j < C; ++j)
          f += b[j] * c[j];
        return f;
      };
      fu = dot(bv[0], col1);
      fuu = dot(bv[0], col2);
      fv = dot(bv[1], col0);
      fuv = dot(bv[1], col1);
      fvv = dot(bv[2], col0);
    }
    const bool free_u = !((u <= 0.0 && fu >= 0.0) || (u >= 1.0 && fu <= 0.0));
    const bool free_v = !((v <= 0.0 && fv >= 0.0) || (v >= 1.0 && fv <= 0.0));
    double du = 0.0, dv = 0.0;
    if (free_u && free_v) {
      const double det = fuu * fvv - fuv * fuv;
      if (!(fuu > 0.0 && det > 0.0)) break;
      du = -(fvv * fu - fuv * fv) / det;
      dv = -(fuu * fv - fuv * fu) / det;
    } else if (free_u) {
      if (!(fuu > 0.0)) break;
      du = -fu / fuu;
    } else if (free_v) {
      if (!(fvv > 0.0)) break;
      dv = -fv / fvv;
    } else {
      break;
    }
    const double nu = std::clamp(u + du, 0.0, 1.0), nv = std::clamp(v + dv, 0.0, 1.0);
    if (!std::isfinite(nu) || !std::isfinite(nv)) break;
    const double moved = std::max(std::abs(nu - u), std::abs(nv - v));
    u = nu;
    v = nv;
    // Quadratic convergence: after a step this short the error left is far below what the
    // geometric Newton resolves in its first step; another step here would not pay.
    if (moved <= 1e-8) break;
  }
}

// bernstein_minimiser_2d for the grids it is instantiated for (bicubic and biquadratic patches);
// false for any other grid (the start is left as it is).
NURBSREG_HOT_CLONES
bool polynomial_start(const double* a, int rows, int cols, double& u, double& v) {
  if (rows == 7 && cols == 7) {
    bernstein_minimiser_2d<7, 7>(a, u, v);
    return true;
  }
  if (rows == 5 && cols == 5) {
    bernstein_minimiser_2d<5, 5>(a, u, v);
    return true;
  }
  return false;
}

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
    const double value =
        newton_core(pp.patch, p, s0, s1, t0, t1, s, t, foot, &st, &normal, abort_at);
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
      const int arg = b.arg >= 0 ? b.arg : first_index_of(n, count, b.lower);
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
          const int edge = monotone_edge(f_derivatives(n, d, rows, cols, false, {b.lower, f_max}));
          if (edge >= 0) {
            reduce_to_edge(edge, n, d, b);
            continue;
          }
        }
      }
    } else {
      const FDerivatives fd = f_derivatives(n, d, rows, cols, true, {b.lower, f_max});
      if (convex(fd)) {
        ++st.convex_terminations;
        newton_box();
        continue;
      }
      const int edge = monotone_edge(fd);
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
    // Split across the direction in which F varies most: that is where the box is "long".
    double var_s = 0.0, var_t = 0.0;
    if (!pp.rational) {
      // The same maxima without the per-element branches (max is order-independent).
      for (int k = 0; k + cols < count; ++k)
        var_s = std::max(var_s, std::abs(n[k + cols] - n[k]));
      for (int i = 0; i < rows; ++i) {
        const double* row = n + i * cols;
        for (int j = 0; j + 1 < cols; ++j)
          var_t = std::max(var_t, std::abs(row[j + 1] - row[j]));
      }
    }
    for (int i = 0; pp.rational && i < rows; ++i) {
      for (int j = 0; j < cols; ++j) {
        const int k = i * cols + j;
        const double f = pp.rational ? n[k] / d[k] : n[k];
        if (i + 1 < rows) {
          const double g = pp.rational ? n[k + cols] / d[k + cols] : n[k + cols];
          var_s = std::max(var_s, std::abs(g - f));
        }
        if (j + 1 < cols) {
          const double g = pp.rational ? n[k + 1] / d[k + 1] : n[k + 1];
          var_t = std::max(var_t, std::abs(g - f));
        }
      }
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

SurfaceScratch::SurfaceScratch()
    : grids(static_cast<std::size_t>(kStackCapacity + 1) * 2 * kGridCapacity),
      boxes(kStackCapacity + 1),
      rows(static_cast<std::size_t>(kStackCapacity + 2) * 2 * (2 * kMaxDegree + 1)),
      intervals(kStackCapacity + 1) {
  order.reserve(kDefaultPatchCapacity);
}

NURBSREG_HOT_CLONES
void PreparedPatch::numerator(const Vec3& point, double* out) const {
  const Vec3 q = point - origin;
  const double qq = q.squaredNorm();
  const int count = rows * cols;
  // Structure-of-arrays copy of E: the loop vectorises.
  const double* ex = e_soa.data();
  const double* ey = ex + count;
  const double* ez = ey + count;
  const double qx = 2.0 * q.x(), qy = 2.0 * q.y(), qz = 2.0 * q.z();
  if (!rational) {
    // D == 1 exactly (prepare_patch), so qq * D == qq: the same values without reading D.
    for (int k = 0; k < count; ++k)
      out[k] = g[k] - (qx * ex[k] + qy * ey[k] + qz * ez[k]) + qq;
    return;
  }
  for (int k = 0; k < count; ++k)
    out[k] = g[k] - (qx * ex[k] + qy * ey[k] + qz * ez[k]) + qq * d[k];
}

PreparedPatch prepare_patch(const BezierPatch& patch) {
  assert(patch.degree_u <= kMaxDegree && patch.degree_v <= kMaxDegree);
  PreparedPatch pp;
  pp.patch = patch;
  pp.box = bounding_box(patch);
  pp.sphere = bounding_sphere(patch);
  pp.origin = pp.sphere.center;
  const int p = patch.degree_u, q = patch.degree_v;
  pp.rows = 2 * p + 1;
  pp.cols = 2 * q + 1;
  const double w0 = patch.cw[0][3];
  pp.rational = false;
  for (const Vec4& c : patch.cw) {
    if (std::abs(c[3] - w0) > 1e-14 * w0) pp.rational = true;
  }
  const int count = pp.rows * pp.cols;
  pp.d.assign(count, 0.0);
  pp.g.assign(count, 0.0);
  pp.e.assign(count, Vec3::Zero());
  // Homogeneous points relative to the origin, w (P - o); weights 1 for polynomial patches.
  std::vector<Vec3> pw(patch.cw.size());
  std::vector<double> w(patch.cw.size());
  for (std::size_t k = 0; k < patch.cw.size(); ++k) {
    const Vec4& c = patch.cw[k];
    w[k] = pp.rational ? c[3] : 1.0;
    pw[k] = w[k] * (c.head<3>() / c[3] - pp.origin);
  }
  // Bernstein product identity B_a^p B_c^p = C(p,a) C(p,c) / C(2p,a+c) B_{a+c}^{2p}.
  const int stride = q + 1;
  for (int a = 0; a <= p; ++a) {
    for (int c = 0; c <= p; ++c) {
      const double bu = binomial(p, a) * binomial(p, c) / binomial(2 * p, a + c);
      for (int b = 0; b <= q; ++b) {
        for (int dd = 0; dd <= q; ++dd) {
          const double beta = bu * binomial(q, b) * binomial(q, dd) / binomial(2 * q, b + dd);
          const int k = (a + c) * pp.cols + (b + dd);
          const int ab = a * stride + b, cd = c * stride + dd;
          pp.d[k] += beta * w[ab] * w[cd];
          pp.g[k] += beta * pw[ab].dot(pw[cd]);
          pp.e[k] += beta * 0.5 * (w[cd] * pw[ab] + w[ab] * pw[cd]);
        }
      }
    }
  }
  if (!pp.rational) std::fill(pp.d.begin(), pp.d.end(), 1.0);
  pp.e_soa.resize(3 * static_cast<std::size_t>(count));
  for (int k = 0; k < count; ++k) {
    for (int c = 0; c < 3; ++c)
      pp.e_soa[static_cast<std::size_t>(c * count + k)] = pp.e[k][c];
  }
  const auto at = [&](int i, int j) { return pp.e[static_cast<std::size_t>(i * pp.cols + j)]; };
  for (int i = 0; i < pp.rows; ++i) {
    for (int j = 0; j < pp.cols; ++j) {
      if (i + 1 < pp.rows) pp.e_s = std::max(pp.e_s, (at(i + 1, j) - at(i, j)).norm());
      if (j + 1 < pp.cols) pp.e_t = std::max(pp.e_t, (at(i, j + 1) - at(i, j)).norm());
      if (i + 2 < pp.rows) {
        pp.e_ss = std::max(pp.e_ss, (at(i + 2, j) - 2.0 * at(i + 1, j) + at(i, j)).norm());
      }
      if (j + 2 < pp.cols) {
        pp.e_tt = std::max(pp.e_tt, (at(i, j + 2) - 2.0 * at(i, j + 1) + at(i, j)).norm());
      }
      if (i + 1 < pp.rows && j + 1 < pp.cols) {
        pp.e_st =
            std::max(pp.e_st, (at(i + 1, j + 1) - at(i + 1, j) - at(i, j + 1) + at(i, j)).norm());
      }
    }
  }
  return pp;
}

namespace {
// Inlined: it then runs in newton_core's own (possibly AVX2) code.
[[gnu::always_inline]] inline Vec3 unit_normal(const Vec3& su, const Vec3& sv) {
  const Vec3 n = su.cross(sv);
  const double scale = su.norm() * sv.norm();
  const double length = n.norm();
  if (scale > 0.0 && length > 1e-12 * scale) return n / length;
  return Vec3::Zero();
}
}  // namespace

namespace {

// newton_on_patch with an optional early exit for a box on which F = |S - p|^2 is known to be
// convex (`abort_at` finite, polynomial patches only): a convex F lies above its tangent plane,
// so F >= F(x) + grad F(x) . (y - x) >= F(x) + Σ min over the box's ends, for every y in the box.
// When that bound reaches abort_at the box cannot beat the caller's best: Newton stops and
// returns +infinity (nothing to offer; s, t and foot are then meaningless).
NURBSREG_HOT_CLONES
double newton_core(const BezierPatch& patch, const Vec3& p, double s0, double s1, double t0,
                   double t1, double& s, double& t, Vec3& foot, SurfaceProjectionStats* stats,
                   Vec3* normal, double abort_at, bool* converged, double settled_step);

}  // namespace

double newton_on_patch(const BezierPatch& patch, const Vec3& p, double s0, double s1, double t0,
                       double t1, double& s, double& t, Vec3& foot, SurfaceProjectionStats* stats,
                       Vec3* normal, bool* converged) {
  return newton_core(patch, p, s0, s1, t0, t1, s, t, foot, stats, normal,
                     std::numeric_limits<double>::infinity(), converged);
}

double newton_to_proven_point(const BezierPatch& patch, const Vec3& p, double s0, double s1,
                              double t0, double t1, double& s, double& t, Vec3& foot, Vec3* normal,
                              bool* converged) {
  // 1e-10 of the patch's parameter range: the foot's error is then ~1e-10 of the patch's size
  // along the surface at most, and the squared distance's ~|H| 1e-20, far below the 1e-11 R the
  // clipping itself does not pursue.
  return newton_core(patch, p, s0, s1, t0, t1, s, t, foot, nullptr, normal,
                     std::numeric_limits<double>::infinity(), converged, 1e-10);
}

namespace {

NURBSREG_HOT_CLONES
double newton_core(const BezierPatch& patch, const Vec3& p, double s0, double s1, double t0,
                   double t1, double& s, double& t, Vec3& foot, SurfaceProjectionStats* stats,
                   Vec3* normal, double abort_at, bool* converged, double settled_step) {
  s = std::clamp(s, s0, s1);
  t = std::clamp(t, t0, t1);
  // Set when the iteration ends at a stationary (KKT) point of the box, not by the iteration cap,
  // a failed line search or a non-finite step.
  bool stationary = false;
  Vec3 d[6];
  patch_derivatives(patch, s, t, d);
  Vec3 r = d[0] - p;
  double f = r.squaredNorm();
  long iterations = 0;
  for (int it = 0; it < 60; ++it) {
    ++iterations;
    const Vec3 &su = d[1], &sv = d[2];
    // Half gradient and half Hessian of F = |S - p|^2.
    const double gs = r.dot(su), gt = r.dot(sv);
    if (abort_at < std::numeric_limits<double>::infinity()) {
      // Tangent-plane lower bound of the convex F over the box (F_s = 2 gs, F_t = 2 gt).
      const double below = f + 2.0 * (std::min(gs * (s0 - s), gs * (s1 - s)) +
                                      std::min(gt * (t0 - t), gt * (t1 - t)));
      if (below >= abort_at) {
        if (stats) stats->newton_iterations += iterations;
        if (converged) *converged = false;
        return std::numeric_limits<double>::infinity();
      }
    }
    const double suu = su.dot(su), svv = sv.dot(sv);
    const double hss = suu + r.dot(d[3]);
    const double hst = su.dot(sv) + r.dot(d[4]);
    const double htt = svv + r.dot(d[5]);
    // Projected Newton: a variable at a bound whose gradient pushes outward is held fixed.
    // A gradient component below rounding (relative 1e-15) counts as zero: stationary. Compared
    // squared: |g| > 1e-15 |r| max(|S_s|, |S_t|) without the three roots.
    const double noise_sq = 1e-30 * f * std::max(suu, svv);
    const bool free_s =
        s1 > s0 && gs * gs > noise_sq && !((s <= s0 && gs > 0) || (s >= s1 && gs < 0));
    const bool free_t =
        t1 > t0 && gt * gt > noise_sq && !((t <= t0 && gt > 0) || (t >= t1 && gt < 0));
    if (!free_s && !free_t) {
      stationary = true;
      break;
    }
    double ds = 0, dt = 0;
    bool newton_step = false;
    if (free_s && free_t) {
      const double det = hss * htt - hst * hst;
      if (hss > 0 && htt > 0 && det > 1e-12 * hss * htt) {
        ds = -(htt * gs - hst * gt) / det;
        dt = -(hss * gt - hst * gs) / det;
        newton_step = true;
      } else {
        // Not locally convex: Gauss-Newton (J^T J is positive semi-definite), regularised for a
        // degenerate parametrisation (a pole, where S_t = 0).
        const double a = su.dot(su), b = su.dot(sv), c = sv.dot(sv);
        const double mu = 1e-10 * (a + c) + 1e-300;
        const double det2 = (a + mu) * (c + mu) - b * b;
        ds = -((c + mu) * gs - b * gt) / det2;
        dt = -((a + mu) * gt - b * gs) / det2;
      }
    } else if (free_s) {
      newton_step = hss > 0;
      ds = -gs / (newton_step ? hss : su.dot(su) + 1e-300);
    } else {
      newton_step = htt > 0;
      dt = -gt / (newton_step ? htt : sv.dot(sv) + 1e-300);
    }
    if (!free_s) ds = 0;
    if (!free_t) dt = 0;
    if (!std::isfinite(ds) || !std::isfinite(dt)) break;
    // Never try to leave the box by more than its size (gradient steps near a pole are huge).
    const double reach = std::max(std::abs(ds) / std::max(s1 - s0, 1e-300),
                                  std::abs(dt) / std::max(t1 - t0, 1e-300));
    if (reach > 1.0) {
      ds /= reach;
      dt /= reach;
    }
    // Converged: the step is below what a parameter in [0, 1] can resolve (the same threshold as
    // `moved` below, without spending an evaluation on it); or it is a full Newton step (positive
    // definite Hessian) below 1e-12 of the box, the size after which the loop below stops anyway
    // (the point is then ~1e-12 of the box from the minimiser: a foot within 1e-12 of the patch's
    // size, F within ~|H| 1e-24; the clipping accepts 1e-11 R), which saves the evaluation of
    // that last step (about one in four of a warm start's, 5% of a warm frame); or below
    // `settled_step` for a Newton step where the caller has proven F strictly convex (the point
    // is then that close to the minimiser and F within ~|H| settled_step^2 of the minimum).
    if (std::max(std::abs(ds), std::abs(dt)) <=
        (newton_step ? std::max(settled_step, 1e-12 * std::max(s1 - s0, t1 - t0)) : 1e-15)) {
      stationary = true;
      break;
    }
    // Rounding in |S - p|^2: S carries ~eps |S| absolute error, so F carries ~2 |r| eps |S|.
    // Only needed when the sufficient-decrease test fails (rarely): computed then (three roots).
    auto f_noise = [&] { return 1e-14 * r.norm() * (d[0].norm() + p.norm()) + 1e-300; };
    // On a box where the caller proved F strictly convex (settled_step above rounding), in the
    // quadratic regime (a full Newton step, both variables free, below 1e-6 of the box) the step
    // after this one is ~1e-12 of the box: the trial point gets S, S_s and S_t only, and when the
    // next Newton step, estimated with this iteration's Hessian (off by ~1e-6 relative), is
    // below settled_step, Newton ends there without second derivatives.
    if (settled_step > 1e-15 && newton_step && free_s && free_t &&
        std::max(std::abs(ds), std::abs(dt)) <= 1e-6 * std::max(s1 - s0, t1 - t0)) {
      const double ns = s + ds, nt = t + dt;
      Vec3 first[3];
      if (ns > s0 && ns < s1 && nt > t0 && nt < t1 &&
          patch_first_derivatives(patch, ns, nt, first)) {
        const Vec3 nr = first[0] - p;
        const double nf = nr.squaredNorm();
        const double ngs = nr.dot(first[1]), ngt = nr.dot(first[2]);
        const double det = hss * htt - hst * hst;
        const double es = (htt * ngs - hst * ngt) / det, et = (hss * ngt - hst * ngs) / det;
        if (nf <= f + f_noise() && std::max(std::abs(es), std::abs(et)) <= settled_step) {
          ++iterations;
          s = ns;
          t = nt;
          d[0] = first[0];
          d[1] = first[1];
          d[2] = first[2];
          f = nf;
          stationary = true;
          break;
        }
      }
    }
    double step = 1.0;
    bool accepted = false;
    double ns = s, nt = t;
    // Trial points get all derivatives at once: the first trial is nearly always accepted and
    // its derivatives are then those of the next iteration.
    Vec3 trial[6];
    for (int ls = 0; ls < 60; ++ls) {
      ns = std::clamp(s + step * ds, s0, s1);
      nt = std::clamp(t + step * dt, t0, t1);
      patch_derivatives(patch, ns, nt, trial);
      const double nf = (trial[0] - p).squaredNorm();
      const double predicted = 2.0 * (gs * (ns - s) + gt * (nt - t));
      const double moved = std::max(std::abs(ns - s), std::abs(nt - t));
      if (nf <= f + 1e-4 * predicted ||
          // In the quadratic regime the change of F drowns in rounding; a short Newton step is
          // still taken (it improves orthogonality) unless it visibly increases F.
          (newton_step && step == 1.0 && moved < 1e-6 && nf <= f + f_noise())) {
        accepted = true;
        break;
      }
      step *= 0.5;
    }
    if (!accepted) break;
    const double moved = std::max(std::abs(ns - s), std::abs(nt - t));
    s = ns;
    t = nt;
    std::copy(trial, trial + 6, d);
    r = d[0] - p;
    f = r.squaredNorm();
    if (moved <= 1e-15) {
      stationary = true;
      break;
    }
    // A full Newton step (positive definite Hessian) of size delta leaves an error of order
    // delta^2 (quadratic convergence): below 1e-12 the next step would be under 1e-15 relative
    // to the box up to the conditioning. We stop there instead of paying for that step.
    if (newton_step && step == 1.0 && moved <= 1e-12 * std::max(s1 - s0, t1 - t0)) {
      stationary = true;
      break;
    }
  }
  if (stats) stats->newton_iterations += iterations;
  foot = d[0];
  if (normal) *normal = unit_normal(d[1], d[2]);
  if (converged) *converged = stationary;
  return f;
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
  return convex(f_derivatives(n, pp.d.data(), pp.rows, pp.cols, true, {range.lo, range.hi}));
}

NURBSREG_HOT_CLONES
double grid_convexity_radius(const double* n, int rows, int cols, double e_ss, double e_tt,
                             double e_st, double r_max) {
  // F's second-derivative ranges on the box (the clipping's own bounds), then `convex` on them
  // widened: N_ij(q) = G_ij - 2 (q - o).E_ij + |q - o|^2, so for |q - a| <= r each second
  // difference moves by at most 2 r |second difference of E| (the constant term has none),
  // scaled like the differences themselves.
  FDerivatives d{};
  if (!second_derivative_ranges(n, rows, cols, d)) return 0.0;  // fails at r = 0 already
  const int m = rows - 1, k = cols - 1;
  const double ks = 2.0 * double(m) * (m - 1) * e_ss, kt = 2.0 * double(k) * (k - 1) * e_tt,
               kst = 2.0 * double(m) * k * e_st;
  const auto holds = [&](double r) {
    FDerivatives f{};
    f.ss = {d.ss.lo - r * ks, d.ss.hi + r * ks};
    f.tt = {d.tt.lo - r * kt, d.tt.hi + r * kt};
    f.st = {d.st.lo - r * kst, d.st.hi + r * kst};
    return convex(f);
  };
  if (!holds(0.0)) return 0.0;
  if (holds(r_max)) return r_max;
  double lo = 0.0, hi = r_max;  // holds(lo), !holds(hi)
  for (int k = 0; k < 30 && hi - lo > 1e-3 * hi; ++k) {
    const double mid = 0.5 * (lo + hi);
    (holds(mid) ? lo : hi) = mid;
  }
  return lo;
}

}  // namespace nurbsreg::engine
