#include "surface/start_minimisers.hpp"

#include <algorithm>
#include <cmath>

#include "bernstein/bernstein_values.hpp"
#include "bernstein/binomial_table.hpp"
#include "nurbsreg/engine/types.hpp"
#include "platform/cpu_dispatch.hpp"
#include "platform/vector_lanes.hpp"

namespace nurbsreg::engine {
namespace {

// Up to the degree of the squared distance along a boundary curve (bernstein_minimiser).
constexpr BinomialTable<2 * kMaxDegree> kWideBinomial;

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

}  // namespace

NURBSREG_HOT_CLONES
double bernstein_minimiser(const double* c, int count, double u) {
  if (count == 7) return bernstein_minimiser_impl<7>(c, count, u);  // bicubic
  if (count == 5) return bernstein_minimiser_impl<5>(c, count, u);  // biquadratic
  return bernstein_minimiser_impl<0>(c, count, u);
}

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

}  // namespace nurbsreg::engine
