#include "warm_certificate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace nurbsreg::engine {
namespace {

// de Casteljau restriction of the 1-D Bernstein polynomial c[0], c[stride], ... (degree n) from
// [0, 1] to [a, b]: the part left of b, then the part of that right of a / b.
void restrict_line(double* c, int n, int stride, double a, double b) {
  if (b < 1.0) {
    for (int r = 1; r <= n; ++r) {
      for (int k = n; k >= r; --k)
        c[k * stride] = (1.0 - b) * c[(k - 1) * stride] + b * c[k * stride];
    }
  }
  const double t = b > 0.0 ? a / b : 0.0;
  if (t > 0.0) {
    for (int r = 1; r <= n; ++r) {
      for (int k = 0; k <= n - r; ++k)
        c[k * stride] = (1.0 - t) * c[k * stride] + t * c[(k + 1) * stride];
    }
  }
}

// `out` = the grid `in` (rows x cols, s along rows) restricted to [s0, s1] x [t0, t1].
void restrict_grid(const double* in, double* out, int rows, int cols, double s0, double s1,
                   double t0, double t1) {
  std::copy(in, in + rows * cols, out);
  for (int j = 0; j < cols; ++j)
    restrict_line(out + j, rows - 1, cols, s0, s1);
  for (int i = 0; i < rows; ++i)
    restrict_line(out + i * cols, cols - 1, 1, t0, t1);
}

struct LocalBox {
  double s0, s1, t0, t1;
};

// Lower bound of F on P \ N: the eight tiles of P around N (the 3 x 3 tiling by N's sides, less
// N), each bounded by its restricted grid's smallest coefficient (convex hull property); a tile
// whose bound is below target_sq is halved once along its longer side and bounded again.
double outside_lower_bound(const double* full, double* grid, int rows, int cols, const LocalBox& n,
                           double target_sq, double rounding) {
  const double s_cuts[4] = {0.0, n.s0, n.s1, 1.0};
  const double t_cuts[4] = {0.0, n.t0, n.t1, 1.0};
  const auto lower = [&](const LocalBox& b) {
    restrict_grid(full, grid, rows, cols, b.s0, b.s1, b.t0, b.t1);
    return *std::min_element(grid, grid + rows * cols) - rounding;
  };
  double bound = target_sq;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      if (a == 1 && b == 1) continue;
      const LocalBox tile{s_cuts[a], s_cuts[a + 1], t_cuts[b], t_cuts[b + 1]};
      if (!(tile.s1 > tile.s0) || !(tile.t1 > tile.t0)) continue;
      double value = lower(tile);
      if (value < bound) {
        LocalBox half0 = tile, half1 = tile;
        if (tile.s1 - tile.s0 >= tile.t1 - tile.t0) {
          half0.s1 = half1.s0 = 0.5 * (tile.s0 + tile.s1);
        } else {
          half0.t1 = half1.t0 = 0.5 * (tile.t0 + tile.t1);
        }
        value = std::min(lower(half0), lower(half1));
      }
      bound = std::min(bound, value);
    }
  }
  return std::max(bound, 0.0);
}

// The float box [center - h, center + h] clipped to [0, 1], rounded outward so it holds center.
void float_range(double center, double h, float& lo, float& hi) {
  lo = static_cast<float>(std::max(0.0, center - h));
  hi = static_cast<float>(std::min(1.0, center + h));
  if (static_cast<double>(lo) > center) lo = std::nextafter(lo, 0.0f);
  if (static_cast<double>(hi) < center) hi = std::nextafter(hi, 1.0f);
  lo = std::max(lo, 0.0f);
  hi = std::min(hi, 1.0f);
}

}  // namespace

PatchCertificate certify_patch(const PreparedPatch& pp, const Vec3& a, double s, double t, double d,
                               double r_max, SurfaceScratch& scratch) {
  PatchCertificate c;
  if (pp.rational || !a.allFinite() || !(r_max > 0.0)) return c;
  const int rows = pp.rows, cols = pp.cols;
  double* full = scratch.grids.data();
  double* grid = full + SurfaceScratch::kGridCapacity;
  pp.numerator(a, full);
  c.radius = grid_convexity_radius(full, rows, cols, pp.e_ss, pp.e_tt, pp.e_st, r_max);
  if (c.radius > 0.0) {
    c.outside_sq = std::numeric_limits<double>::infinity();
    return c;
  }
  // The same rounding allowance as the clipping's (coefficients carry ~eps reach^2).
  const double reach = pp.sphere.radius + (a - pp.origin).norm();
  const double rounding = 1e-14 * reach * reach;
  for (const double h : {0.25, 0.1}) {
    float_range(s, h, c.s0, c.s1);
    float_range(t, h, c.t0, c.t1);
    const double ws = double(c.s1) - c.s0, wt = double(c.t1) - c.t0;
    if (!(ws > 0.0) || !(wt > 0.0)) continue;
    restrict_grid(full, grid, rows, cols, c.s0, c.s1, c.t0, c.t1);
    // E restricted to the box: its second differences are those of the second derivatives'
    // coefficients scaled by the box's widths, convex combinations of the whole patch's.
    c.radius = grid_convexity_radius(grid, rows, cols, pp.e_ss * ws * ws, pp.e_tt * wt * wt,
                                     pp.e_st * ws * wt, r_max);
    if (c.radius > 0.0) {
      const double target = (d + 2.0 * c.radius) * (d + 2.0 * c.radius);
      c.outside_sq =
          outside_lower_bound(full, grid, rows, cols, {c.s0, c.s1, c.t0, c.t1}, target, rounding);
      return c;
    }
  }
  c = PatchCertificate{};
  return c;
}

}  // namespace nurbsreg::engine
