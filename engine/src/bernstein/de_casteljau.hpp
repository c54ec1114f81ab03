#pragma once
// Internal: the de Casteljau scheme, the one implementation of the engine's Bézier splitting:
// at any t for control points (BezierCurve::split, BezierPatch::split, the reach bounds' cells)
// and at 1/2 for coefficient grids and pieces (the surface clipping's boxes, the curve clipping's
// rational functions, the trim loops' pieces, Ma-Hewitt's nets). Each caller gets exactly the
// operations, in the same order, of the copy it had before.

#include <cstddef>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine {

// Largest grid side: the squared distance of a patch of degree kMaxDegree has degree 2 kMaxDegree.
constexpr int kMaxGridSide = 2 * kMaxDegree + 1;

// The coefficients a[i * stride], i = 0..n (n < kMaxGridSide), split into the parts over [0, t]
// (left) and [t, 1] (right), written at out_stride; mix(x, y) is the point at t between two
// neighbours. The input is copied first, so left or right may alias it.
template <class T, class Mix>
[[gnu::always_inline]] inline void de_casteljau(const T* a, std::ptrdiff_t stride, int n, T* left,
                                                T* right, std::ptrdiff_t out_stride, Mix mix) {
  if (n < 0 || n >= kMaxGridSide) __builtin_unreachable();  // callers' degrees (no code)
  T work[kMaxGridSide];
  for (int i = 0; i <= n; ++i)
    work[i] = a[i * stride];
  left[0] = work[0];
  right[n * out_stride] = work[n];
  for (int r = 1; r <= n; ++r) {
    for (int i = 0; i <= n - r; ++i)
      work[i] = mix(work[i], work[i + 1]);
    left[r * out_stride] = work[0];
    right[(n - r) * out_stride] = work[n - r];
  }
}

// At 1/2: 0.5 (x + y) (one multiplication, exact scaling).
template <class T>
[[gnu::always_inline]] inline void halve(const T* a, std::ptrdiff_t stride, int n, T* left,
                                         T* right) {
  de_casteljau(a, stride, n, left, right, stride,
               [](const T& x, const T& y) -> T { return 0.5 * (x + y); });
}

// The clipping's grids (rows x cols, row-major, in place: `low` keeps [s0, mid] of the split
// direction, `high` gets [mid, s1]). Along s (rows):
void split_rows(double* low, double* high, int rows, int cols);
// Along s at any x in (0, 1): `low` keeps [0, x], `high` gets [x, 1] (mix (1 - x) a + x b: the
// certificates' tilings, where N's sides fall anywhere).
void split_rows_at(double* low, double* high, int rows, int cols, double x);
// One contiguous row of `count` values (along t):
void split_line(double* low, double* high, int count);

// Along t: every row split as split_line splits it (the same values).
void split_cols(double* low, double* high, int rows, int cols);

}  // namespace nurbsreg::engine
