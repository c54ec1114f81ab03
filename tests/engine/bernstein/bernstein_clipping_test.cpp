// The 1-D rational Bernstein clipping driver (bernstein_clipping.hpp) on its own: halving
// reproduces the function, Property 2's test, and circular_clip finds the global minimum of
// random rational Bernstein functions (oracle: dense sampling).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "bernstein/bernstein_clipping.hpp"
#include "nurbsreg/engine/bezier.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::uniform;

// f at local s of the node's interval, straight from the definition.
double value_at(const RationalBernstein& f, double s) {
  double b[kMaxBernsteinDegree + 1];
  bernstein(f.degree, s, b);
  double num = 0.0;
  double den = 0.0;
  for (int k = 0; k <= f.degree; ++k) {
    num += b[k] * f.num[k];
    den += b[k] * f.den[k];
  }
  return num / den;
}

RationalBernstein random_function(std::mt19937_64& rng, int degree) {
  RationalBernstein f;
  f.degree = degree;
  f.depth = 0;
  f.speculative = false;
  f.a = 0.0;
  f.b = 1.0;
  for (int k = 0; k <= degree; ++k) {
    f.den[k] = std::exp(uniform(rng, -1.0, 1.0));
    f.num[k] = f.den[k] * uniform(rng, 0.0, 4.0);
  }
  return f;
}

TEST(BernsteinClipping, SplitHalfReproducesTheFunction) {
  std::mt19937_64 rng(1);
  for (int degree : {1, 2, 6, 13, kMaxBernsteinDegree}) {
    const RationalBernstein f = random_function(rng, degree);
    RationalBernstein left;
    RationalBernstein right;
    split_half(f, left, right);
    EXPECT_EQ(left.b, 0.5);
    EXPECT_EQ(right.a, 0.5);
    EXPECT_EQ(left.depth, 1);
    for (int i = 0; i <= 20; ++i) {
      const double s = i / 20.0;
      EXPECT_NEAR(value_at(left, s), value_at(f, 0.5 * s), 1e-13);
      EXPECT_NEAR(value_at(right, s), value_at(f, 0.5 + 0.5 * s), 1e-13);
    }
    // In place: the left half may overwrite its source.
    RationalBernstein g = f;
    split_half(g, g, right);
    EXPECT_NEAR(value_at(g, 0.3), value_at(f, 0.15), 1e-13);
  }
}

TEST(BernsteinClipping, Property2) {
  const double down_up[] = {3, 2, 1, 1, 2, 5};
  const double rising[] = {1, 2, 3};
  const double falling[] = {3, 2, 1};
  const double constant[] = {2, 2, 2};
  const double two_valleys[] = {1, 3, 2, 4};
  const double hump[] = {1, 2, 1};
  EXPECT_TRUE(is_unimodal(down_up, 5));
  EXPECT_TRUE(is_unimodal(rising, 2));
  EXPECT_TRUE(is_unimodal(falling, 2));
  EXPECT_TRUE(is_unimodal(constant, 2));
  EXPECT_FALSE(is_unimodal(two_valleys, 3));
  EXPECT_FALSE(is_unimodal(hump, 2));
}

TEST(BernsteinClipping, FindsTheGlobalMinimum) {
  std::mt19937_64 rng(2);
  ClippingCounters total;
  for (int trial = 0; trial < 300; ++trial) {
    const RationalBernstein f = random_function(rng, 2 + trial % 11);
    // Oracle: dense samples of the whole function.
    double oracle = std::numeric_limits<double>::infinity();
    for (int i = 0; i <= 20000; ++i)
      oracle = std::min(oracle, value_at(f, i / 20000.0));
    // Terminal: minimise on [a, b] by dense sampling + golden section around the best sample
    // (a stand-in for the geometric solver of the real callers).
    double found = std::numeric_limits<double>::infinity();
    const auto terminal = [&](const RationalBernstein& node, const double*, TerminalReason) {
      double best_s = 0.0;
      double best = std::numeric_limits<double>::infinity();
      for (int i = 0; i <= 64; ++i) {
        const double v = value_at(f, node.a + (node.b - node.a) * i / 64.0);
        if (v < best) {
          best = v;
          best_s = i / 64.0;
        }
      }
      double lo = std::max(0.0, best_s - 1.0 / 64);
      double hi = std::min(1.0, best_s + 1.0 / 64);
      for (int it = 0; it < 80; ++it) {
        const double m1 = lo + 0.382 * (hi - lo);
        const double m2 = lo + 0.618 * (hi - lo);
        const double v1 = value_at(f, node.a + (node.b - node.a) * m1);
        const double v2 = value_at(f, node.a + (node.b - node.a) * m2);
        (v1 < v2 ? hi : lo) = v1 < v2 ? m2 : m1;
        best = std::min(best, std::min(v1, v2));
      }
      found = std::min(found, best);
      return best;
    };
    double alpha = std::numeric_limits<double>::infinity();
    ClippingCounters counters;
    circular_clip(f, 1e-13, alpha, terminal, counters);
    EXPECT_LE(found, oracle + 1e-12) << "trial " << trial;
    EXPECT_GE(alpha, found - 1e-12);  // alpha stays an upper bound of what was found
    EXPECT_GT(counters.terminals, 0u);
    total.subdivisions += counters.subdivisions;
    total.eliminated += counters.eliminated;
    total.depth_limit_hits += counters.depth_limit_hits;
  }
  EXPECT_GT(total.eliminated, 0u);  // Property 1 did prune
  EXPECT_EQ(total.depth_limit_hits, 0u);
}

}  // namespace
}  // namespace nurbsreg::engine
