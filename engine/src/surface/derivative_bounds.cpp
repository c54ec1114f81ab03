// The convexity tests of derivative_bounds.hpp that run as their own (dispatched) functions.

#include "surface/derivative_bounds.hpp"

namespace nurbsreg::engine {

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

NURBSREG_HOT_CLONES
double grid_convexity_radius_widened(const double* h, int rows, int cols, const Widening& w,
                                     double r_max) {
  FDerivatives d{};
  if (!second_derivative_ranges(h, rows, cols, d)) return 0.0;  // fails at r = 0 already
  const int m = rows - 1, k = cols - 1;
  const double ks = double(m) * (m - 1), kt = double(k) * (k - 1), kst = double(m) * k;
  const auto holds = [&](double r) {
    const double ss = ks * (w.fixed_ss + r * w.lin_ss + r * r * w.quad_ss);
    const double tt = kt * (w.fixed_tt + r * w.lin_tt + r * r * w.quad_tt);
    const double st = kst * (w.fixed_st + r * w.lin_st + r * r * w.quad_st);
    FDerivatives f{};
    f.ss = {d.ss.lo - ss, d.ss.hi + ss};
    f.tt = {d.tt.lo - tt, d.tt.hi + tt};
    f.st = {d.st.lo - st, d.st.hi + st};
    return convex(f);
  };
  if (!holds(0.0)) return 0.0;
  if (holds(r_max)) return r_max;
  double lo = 0.0, hi = r_max;  // holds(lo), !holds(hi)
  for (int n = 0; n < 30 && hi - lo > 1e-3 * hi; ++n) {
    const double mid = 0.5 * (lo + hi);
    (holds(mid) ? lo : hi) = mid;
  }
  return lo;
}

}  // namespace nurbsreg::engine
