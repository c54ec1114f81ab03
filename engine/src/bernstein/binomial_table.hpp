#pragma once
// Internal: binomial coefficients as a compile-time table (Bernstein bases, Bézier products).

namespace nurbsreg::engine {

// C(n, i) for n <= N, exact in double (C(24, 12) < 2^53).
template <int N>
struct BinomialTable {
  double c[N + 1][N + 1] = {};
  constexpr BinomialTable() {
    for (int n = 0; n <= N; ++n) {
      c[n][0] = c[n][n] = 1.0;
      for (int i = 1; i < n; ++i)
        c[n][i] = c[n - 1][i - 1] + c[n - 1][i];
    }
  }
};

}  // namespace nurbsreg::engine
