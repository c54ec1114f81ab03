// The clipping's grid splits (split_rows, split_cols: whole rows or columns of the work at once,
// in vector lanes) against the one-line scheme they replace, halve() on every column or row:
// bit for bit, on every grid shape the clipping can meet (up to kMaxGridSide on a side), with
// values of mixed signs and magnitudes. Both halves, and the input slot must hold the low half.
// split_rows_at (the certificates' tilings: a split anywhere) against de_casteljau() down every
// column bit for bit, and against the polynomial itself: each piece, evaluated as a Bernstein sum,
// is the column's polynomial on its part of [0, 1].
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "bernstein/de_casteljau.hpp"

namespace nurbsreg::engine {
namespace {

std::vector<double> random_grid(std::mt19937_64& rng, int count) {
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-30, 30);
  std::vector<double> g(static_cast<std::size_t>(count));
  for (double& x : g)
    x = std::ldexp(mantissa(rng), exponent(rng));
  return g;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0;
}

TEST(DeCasteljauGrid, SplitsMatchHalvingEveryLineBitForBit) {
  std::mt19937_64 rng(2026);
  for (int rows = 1; rows <= kMaxGridSide; ++rows) {
    for (int cols = 1; cols <= kMaxGridSide; ++cols) {
      const int count = rows * cols;
      const std::vector<double> grid = random_grid(rng, count);
      // Along s: halve() down every column.
      std::vector<double> low_ref = grid, high_ref(grid.size());
      for (int j = 0; j < cols; ++j)
        halve(low_ref.data() + j, cols, rows - 1, low_ref.data() + j, high_ref.data() + j);
      std::vector<double> low = grid, high(grid.size(), 7.0);
      split_rows(low.data(), high.data(), rows, cols);
      EXPECT_TRUE(same_bits(low, low_ref)) << rows << " x " << cols << " rows, low half";
      EXPECT_TRUE(same_bits(high, high_ref)) << rows << " x " << cols << " rows, high half";
      // Along t: halve() along every row.
      low_ref = grid;
      for (int i = 0; i < rows; ++i)
        halve(low_ref.data() + i * cols, 1, cols - 1, low_ref.data() + i * cols,
              high_ref.data() + i * cols);
      low = grid;
      std::fill(high.begin(), high.end(), 7.0);
      split_cols(low.data(), high.data(), rows, cols);
      EXPECT_TRUE(same_bits(low, low_ref)) << rows << " x " << cols << " columns, low half";
      EXPECT_TRUE(same_bits(high, high_ref)) << rows << " x " << cols << " columns, high half";
      // split_line is split_cols on one row.
      low = std::vector<double>(grid.begin(), grid.begin() + cols);
      std::vector<double> line_high(static_cast<std::size_t>(cols));
      split_line(low.data(), line_high.data(), cols);
      EXPECT_TRUE(std::memcmp(low.data(), low_ref.data(), sizeof(double) * cols) == 0);
      EXPECT_TRUE(std::memcmp(line_high.data(), high_ref.data(), sizeof(double) * cols) == 0);
    }
  }
}

// The Bernstein polynomial with coefficients c[0..n] at u, summed directly (no de Casteljau).
double bernstein_sum(const std::vector<double>& c, double u) {
  const int n = static_cast<int>(c.size()) - 1;
  double sum = 0.0, binomial = 1.0;
  for (int i = 0; i <= n; ++i) {
    sum += binomial * std::pow(u, i) * std::pow(1.0 - u, n - i) * c[static_cast<std::size_t>(i)];
    binomial = binomial * (n - i) / (i + 1);
  }
  return sum;
}

TEST(DeCasteljauGrid, SplitsAnywhereGiveThePolynomialOnEachPart) {
  std::mt19937_64 rng(2027);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (const double x : {0.5, 0.1, 0.73, 1e-3, 0.999}) {
    for (int rows = 1; rows <= kMaxGridSide; ++rows) {
      for (const int cols : {1, 3, 8, kMaxGridSide}) {
        std::vector<double> grid(static_cast<std::size_t>(rows * cols));
        for (double& v : grid)
          v = unit(rng);
        std::vector<double> low_ref = grid, high_ref(grid.size());
        for (int j = 0; j < cols; ++j) {
          de_casteljau(low_ref.data() + j, cols, rows - 1, low_ref.data() + j, high_ref.data() + j,
                       cols, [x](double a, double b) { return (1.0 - x) * a + x * b; });
        }
        std::vector<double> low = grid, high(grid.size(), 7.0);
        split_rows_at(low.data(), high.data(), rows, cols, x);
        EXPECT_TRUE(same_bits(low, low_ref)) << rows << " x " << cols << " at " << x;
        EXPECT_TRUE(same_bits(high, high_ref)) << rows << " x " << cols << " at " << x;
        for (int j = 0; j < cols; ++j) {
          std::vector<double> column, left, right;
          for (int i = 0; i < rows; ++i) {
            const std::size_t k = static_cast<std::size_t>(i * cols + j);
            column.push_back(grid[k]);
            left.push_back(low[k]);
            right.push_back(high[k]);
          }
          for (const double u : {0.0, 0.3, 0.5, 0.9, 1.0}) {
            EXPECT_NEAR(bernstein_sum(left, u), bernstein_sum(column, x * u), 1e-12)
                << rows << " x " << cols << " at " << x << ", column " << j << ", u " << u;
            EXPECT_NEAR(bernstein_sum(right, u), bernstein_sum(column, x + (1.0 - x) * u), 1e-12)
                << rows << " x " << cols << " at " << x << ", column " << j << ", u " << u;
          }
        }
      }
    }
  }
}

}  // namespace
}  // namespace nurbsreg::engine
