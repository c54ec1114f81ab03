// The clipping's box tests in vector lanes (surface/box_tests.hpp) against the scalar bounds they
// replace (derivative_bounds.hpp): rational_box_test against convex(f_derivatives(...)) then
// monotone_edge, convex_polynomial against second_derivative_ranges + convex, and
// polynomial_monotone_edge against monotone_edge(f_derivatives(..., false, ...)); for 2 and 4
// lanes (the baseline and AVX2 versions), on random grids of every size the clipping makes, near
// convex, monotone and neither.
#include <gtest/gtest.h>

#include <random>

#include "surface/box_tests.hpp"

namespace nurbsreg::engine {
namespace {

// A grid of F-like coefficients: a paraboloid about (a, b) in the box's local coordinates
// (outside the box: a monotone F, inside: a convex one), tilted by c s t, plus noise.
void fill(std::mt19937_64& rng, int rows, int cols, double* n, double* d, bool rational) {
  std::uniform_real_distribution<double> u(-0.5, 1.5), noise(-0.02, 0.02), w(0.5, 2.0);
  const double a = u(rng), b = u(rng), c = noise(rng) * 50.0;
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      const double s = rows > 1 ? double(i) / (rows - 1) : 0.5;
      const double t = cols > 1 ? double(j) / (cols - 1) : 0.5;
      const double dk = rational ? w(rng) : 1.0;
      d[i * cols + j] = dk;
      n[i * cols + j] = dk * ((s - a) * (s - a) + (t - b) * (t - b) + c * s * t + noise(rng));
    }
  }
}

TEST(BoxTests, LanesMatchTheScalarBounds) {
  std::mt19937_64 rng(26);
  static double n[SurfaceScratch::kGridCapacity], d[SurfaceScratch::kGridCapacity];
  int convex_seen = 0, edge_seen = 0, neither_seen = 0;
  for (int rows = 1; rows <= 2 * kMaxDegree + 1; ++rows) {
    for (int cols = 1; cols <= 2 * kMaxDegree + 1; ++cols) {
      for (int trial = 0; trial < 12; ++trial) {
        const bool rational = trial % 2 == 1;
        fill(rng, rows, cols, n, d, rational);
        double lo = n[0] / d[0], hi = lo;
        for (int k = 0; k < rows * cols; ++k) {
          lo = std::min(lo, n[k] / d[k]);
          hi = std::max(hi, n[k] / d[k]);
        }
        if (rational) {
          const FDerivatives f = f_derivatives(n, d, rows, cols, true, {lo, hi});
          const int want = convex(f) ? kConvexBox : monotone_edge(f);
          EXPECT_EQ(rational_box_test_lanes<2>(n, d, rows, cols, lo, hi), want)
              << rows << " x " << cols;
          EXPECT_EQ(rational_box_test_lanes<4>(n, d, rows, cols, lo, hi), want)
              << rows << " x " << cols;
          (want == kConvexBox ? convex_seen : want >= 0 ? edge_seen : neither_seen) += 1;
        } else {
          FDerivatives f{};
          const bool want = second_derivative_ranges(n, rows, cols, f) && convex(f);
          EXPECT_EQ(convex_polynomial_lanes<2>(n, rows, cols), want) << rows << " x " << cols;
          EXPECT_EQ(convex_polynomial_lanes<4>(n, rows, cols), want) << rows << " x " << cols;
          const int edge = monotone_edge(f_derivatives(n, d, rows, cols, false, {lo, hi}));
          EXPECT_EQ(polynomial_monotone_edge(n, rows, cols), edge) << rows << " x " << cols;
          (want ? convex_seen : edge >= 0 ? edge_seen : neither_seen) += 1;
        }
      }
    }
  }
  // Every outcome occurs (the comparison is not vacuous).
  EXPECT_GT(convex_seen, 20);
  EXPECT_GT(edge_seen, 100);
  EXPECT_GT(neither_seen, 100);
}

}  // namespace
}  // namespace nurbsreg::engine
