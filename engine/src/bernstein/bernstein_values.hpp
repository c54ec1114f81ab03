#pragma once
// Internal: Bernstein basis values and first and second derivatives at a parameter, from one table
// of powers: the inner cost of the Newton on the geometry (patch_derivatives.cpp) and of the 2-D
// start minimiser (start_minimisers.cpp). For the TUs that inline them into their hot kernels.

#include <utility>

#include "bernstein/binomial_table.hpp"
#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine {
namespace {

constexpr BinomialTable<kMaxDegree> kBinomial;

// Bernstein values and first and second derivatives of degree n at t in [0, 1]:
// B_i^m = C(m, i) t^i (1 - t)^(m - i) for m = n, n - 1, n - 2 from one table of powers (all terms
// positive: no cancellation), then dB_i^n/dt = n (B_{i-1}^{n-1} - B_i^{n-1}) and the second
// difference for d2 (The NURBS Book eq. 1.9). Only entries 0..n are written. The loops, for any
// degree: bernstein_012 below takes the unrolled kernel of its degree instead (the same bits).
[[maybe_unused]] void bernstein_012_loops(int n, double t, double* b0, double* b1, double* b2) {
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

// Fixed degree N: Bernstein values and derivatives with compile-time loop bounds (unrolled),
// bit for bit bernstein_012(N, ...). Unrolled before the loop vectoriser sees the loops: it
// turned them into vector loads of the scalars just stored (the powers read in reverse), each
// waiting for its stores to retire, and the basis then cost several times the straight code
// (bench/README.md, seventeenth pass).
template <int N>
[[gnu::always_inline]] inline void bernstein_012_fixed(double t, double* b0, double* b1,
                                                       double* b2) {
  static_assert(N >= 1 && N <= kMaxDegree);
  const double u = 1.0 - t;
  double tp[N + 1], up[N + 1];
  tp[0] = up[0] = 1.0;
#pragma GCC unroll 16
  for (int k = 1; k <= N; ++k) {
    tp[k] = tp[k - 1] * t;
    up[k] = up[k - 1] * u;
  }
#pragma GCC unroll 16
  for (int i = 0; i <= N; ++i)
    b0[i] = kBinomial.c[N][i] * tp[i] * up[N - i];
  double l1[N + 2];
  l1[0] = l1[N + 1] = 0.0;
#pragma GCC unroll 16
  for (int i = 0; i <= N - 1; ++i)
    l1[i + 1] = kBinomial.c[N - 1][i] * tp[i] * up[N - 1 - i];
#pragma GCC unroll 16
  for (int i = 0; i <= N; ++i)
    b1[i] = N * (l1[i] - l1[i + 1]);
  if constexpr (N < 2) {
    // Linear: no second derivative (bernstein_012's zeros).
    for (int i = 0; i <= N; ++i)
      b2[i] = 0.0;
  } else {
    double l2[N + 3];
    l2[0] = l2[1] = l2[N + 1] = l2[N + 2] = 0.0;
#pragma GCC unroll 16
    for (int i = 0; i <= N - 2; ++i)
      l2[i + 2] = kBinomial.c[N - 2][i] * tp[i] * up[N - 2 - i];
#pragma GCC unroll 16
    for (int i = 0; i <= N; ++i)
      b2[i] = double(N * (N - 1)) * (l2[i] - 2.0 * l2[i + 1] + l2[i + 2]);
  }
}

// bernstein_012_loops' values, from the unrolled kernel of degree n (the loops for degree 0).
template <int... N>
[[gnu::always_inline]] inline void bernstein_012_dispatch(std::integer_sequence<int, N...>, int n,
                                                          double t, double* b0, double* b1,
                                                          double* b2) {
  if (!((n == N + 1 ? (bernstein_012_fixed<N + 1>(t, b0, b1, b2), true) : false) || ...)) {
    bernstein_012_loops(n, t, b0, b1, b2);
  }
}

[[maybe_unused]] void bernstein_012(int n, double t, double* b0, double* b1, double* b2) {
  bernstein_012_dispatch(std::make_integer_sequence<int, kMaxDegree>{}, n, t, b0, b1, b2);
}

}  // namespace
}  // namespace nurbsreg::engine
