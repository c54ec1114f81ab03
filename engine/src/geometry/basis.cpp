#include "geometry/basis.hpp"

#include <algorithm>
#include <cassert>

namespace nurbsreg::engine {

int find_span(int degree, std::span<const double> knots, int count, double u) {
  const double lo = knots[degree];
  const double hi = knots[count];
  u = std::clamp(u, lo, hi);
  if (u >= hi) {
    // The domain end belongs to the last non-empty span.
    int span = count - 1;
    while (span > degree && knots[span] >= knots[span + 1])
      --span;
    return span;
  }
  // Binary search for knots[span] <= u < knots[span + 1] over [degree, count - 1].
  int low = degree;
  int high = count;
  while (high - low > 1) {
    const int mid = (low + high) / 2;
    if (u < knots[mid]) {
      high = mid;
    } else {
      low = mid;
    }
  }
  return low;
}

void basis_functions(int span, double u, int degree, std::span<const double> knots,
                     double* values) {
  double left[kMaxDegree + 1];
  double right[kMaxDegree + 1];
  values[0] = 1.0;
  for (int j = 1; j <= degree; ++j) {
    left[j] = u - knots[span + 1 - j];
    right[j] = knots[span + j] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      const double temp = values[r] / (right[r + 1] + left[j - r]);
      values[r] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    values[j] = saved;
  }
}

void basis_derivatives(int span, double u, int degree, std::span<const double> knots, int n,
                       double (*ders)[kMaxDegree + 1]) {
  assert(n <= kMaxDerivative && degree <= kMaxDegree);
  double ndu[kMaxDegree + 1][kMaxDegree + 1];
  double a[2][kMaxDegree + 1];
  double left[kMaxDegree + 1];
  double right[kMaxDegree + 1];
  ndu[0][0] = 1.0;
  for (int j = 1; j <= degree; ++j) {
    left[j] = u - knots[span + 1 - j];
    right[j] = knots[span + j] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      ndu[j][r] = right[r + 1] + left[j - r];  // lower triangle: knot differences
      const double temp = ndu[r][j - 1] / ndu[j][r];
      ndu[r][j] = saved + right[r + 1] * temp;  // upper triangle: basis functions
      saved = left[j - r] * temp;
    }
    ndu[j][j] = saved;
  }
  for (int j = 0; j <= degree; ++j)
    ders[0][j] = ndu[j][degree];
  const int orders = std::min(n, degree);
  for (int r = 0; r <= degree; ++r) {
    int s1 = 0;
    int s2 = 1;
    a[0][0] = 1.0;
    for (int k = 1; k <= orders; ++k) {
      double d = 0.0;
      const int rk = r - k;
      const int pk = degree - k;
      if (r >= k) {
        a[s2][0] = a[s1][0] / ndu[pk + 1][rk];
        d = a[s2][0] * ndu[rk][pk];
      }
      const int j1 = rk >= -1 ? 1 : -rk;
      const int j2 = (r - 1 <= pk) ? k - 1 : degree - r;
      for (int j = j1; j <= j2; ++j) {
        a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][rk + j];
        d += a[s2][j] * ndu[rk + j][pk];
      }
      if (r <= pk) {
        a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
        d += a[s2][k] * ndu[r][pk];
      }
      ders[k][r] = d;
      std::swap(s1, s2);
    }
  }
  int factor = degree;
  for (int k = 1; k <= orders; ++k) {
    for (int j = 0; j <= degree; ++j)
      ders[k][j] *= factor;
    factor *= degree - k;
  }
  // Orders above the degree vanish; A2.3 leaves them unset.
  for (int k = orders + 1; k <= n; ++k) {
    for (int j = 0; j <= degree; ++j)
      ders[k][j] = 0.0;
  }
}

}  // namespace nurbsreg::engine
