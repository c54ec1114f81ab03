#pragma once
// Golden-section search for test references: the smallest value of f seen after `iterations`
// shrinks of [a, b] (f unimodal on the bracket; elsewhere still an upper bound of the minimum).

#include <algorithm>
#include <cmath>

namespace nurbsreg::test {

template <class F>
double golden_section_minimum(F&& f, double a, double b, int iterations) {
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double x1 = b - g * (b - a), x2 = a + g * (b - a), f1 = f(x1), f2 = f(x2);
  for (int it = 0; it < iterations; ++it) {
    if (f1 < f2) {
      b = x2, x2 = x1, f2 = f1, x1 = b - g * (b - a), f1 = f(x1);
    } else {
      a = x1, x1 = x2, f1 = f2, x2 = a + g * (b - a), f2 = f(x2);
    }
  }
  return std::min(f1, f2);
}

}  // namespace nurbsreg::test
