#include "proofs/warm_certificate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "bernstein/de_casteljau.hpp"
#include "surface/derivative_bounds.hpp"
#include "surface/patch_newton.hpp"

namespace nurbsreg::engine {
namespace {

// `out` = the grid `in` (rows x cols, s along rows) restricted from [0, 1] to [s0, s1] in s: on
// every column, the de Casteljau restriction of its Bernstein polynomial (degree rows - 1), first
// to the part left of s1, then to the part of that right of s0 / s1. The columns are the inner
// loop (whole rows at a time, which vectorises).
void restrict_s(const double* in, double* out, int rows, int cols, double s0, double s1) {
  std::copy(in, in + rows * cols, out);
  const int n = rows - 1;
  if (s1 < 1.0) {
    for (int r = 1; r <= n; ++r) {
      for (int k = n; k >= r; --k) {
        double* row = out + k * cols;
        const double* prev = row - cols;
        for (int j = 0; j < cols; ++j)
          row[j] = (1.0 - s1) * prev[j] + s1 * row[j];
      }
    }
  }
  const double t = s1 > 0.0 ? s0 / s1 : 0.0;
  if (t > 0.0) {
    for (int r = 1; r <= n; ++r) {
      for (int k = 0; k <= n - r; ++k) {
        double* row = out + k * cols;
        const double* next = row + cols;
        for (int j = 0; j < cols; ++j)
          row[j] = (1.0 - t) * row[j] + t * next[j];
      }
    }
  }
}

// `out` (cols x rows) = the transpose of `in` (rows x cols): a restriction in t is then one in s
// of the transpose (whole rows again), with the same values.
void transpose(const double* in, double* out, int rows, int cols) {
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j)
      out[j * rows + i] = in[i * cols + j];
  }
}

// The smallest of x[0, n): four running minima (independent chains, which vectorise), then theirs.
double smallest_of(const double* x, int n) {
  const double inf = std::numeric_limits<double>::infinity();
  double m[4] = {inf, inf, inf, inf};
  int k = 0;
  for (; k + 4 <= n; k += 4) {
    for (int l = 0; l < 4; ++l)
      m[l] = std::min(m[l], x[k + l]);
  }
  for (; k < n; ++k)
    m[0] = std::min(m[0], x[k]);
  return std::min(std::min(m[0], m[1]), std::min(m[2], m[3]));
}

struct LocalBox {
  double s0, s1, t0, t1;
  // All of the patch's [0, 1]^2.
  bool whole() const { return s0 == 0.0 && s1 == 1.0 && t0 == 0.0 && t1 == 1.0; }
};

// `out` = the grid `in` restricted to the box (s first, then t), through `work` and `strip`.
void restrict_grid(const double* in, double* out, double* work, double* strip, int rows, int cols,
                   const LocalBox& b) {
  restrict_s(in, work, rows, cols, b.s0, b.s1);
  transpose(work, strip, rows, cols);
  restrict_s(strip, work, cols, rows, b.t0, b.t1);
  transpose(work, out, cols, rows);
}

// The grid (rows x cols, s along rows) cut at c0 < c1 along s into [0, c0], [c0, c1] and [c1, 1]:
// pieces[0] holds the grid on entry; a piece of zero width ([0, 0] or [1, 1]) is left as is.
// Two de Casteljau splits, the second at c1's place within [c0, 1].
void cut_in_three(double* const pieces[3], int rows, int cols, double c0, double c1) {
  if (c0 > 0.0) {
    split_rows_at(pieces[0], pieces[1], rows, cols, c0);
  } else {
    std::copy(pieces[0], pieces[0] + rows * cols, pieces[1]);
  }
  if (c1 < 1.0) split_rows_at(pieces[1], pieces[2], rows, cols, (c1 - c0) / (1.0 - c0));
}

// Lower bound of F on P \ N: the eight tiles of P around N (the 3 x 3 tiling by N's sides, less
// N), each bounded by its grid's smallest coefficient (convex hull property), for a rational patch
// F = N / D its smallest ratio of coefficients (D > 0), less the rounding allowance; a tile whose
// bound is below target_sq is halved once and its halves bounded: a tile beside N across N's own
// range (about the foot, where F's coefficients along that range dip below its values: a side
// tile of a small N stayed near d^2 whatever its distance) and a corner tile wider in s along s,
// the others along t. The tiles come from splits, not from restrictions of the whole grid one by
// one: the grid cut in three along s at N's sides, each column transposed and cut in three along
// t, a tile halved in place (8 split passes a grid, against up to 32 for the restrictions). The
// splits are convex combinations, good to a few ulps of the largest coefficient, far inside the
// allowance. `grids`: 2 x 8 scratch grids (numerator's, then the denominator's).
template <bool kRational>
double tiled_lower_bound(const double* full_n, const double* full_d, int rows, int cols,
                         const LocalBox& box, double target_sq, double rounding, double* grids) {
  constexpr int kCap = SurfaceScratch::kGridCapacity;
  constexpr int kGrids = kRational ? 2 : 1;
  const double* full[2] = {full_n, full_d};
  double* column[2][3];
  double* tile[2][3];
  double* half[2];
  for (int g = 0; g < kGrids; ++g) {
    double* base = grids + g * 8 * kCap;
    for (int k = 0; k < 3; ++k) {
      column[g][k] = base + k * kCap;
      tile[g][k] = base + (3 + k) * kCap;
    }
    half[g] = base + 6 * kCap;
  }
  const int size = rows * cols;
  // The smallest coefficient (ratio) of the tile grids at `n` (and `d`).
  const auto smallest = [&](const double* n, const double* d) {
    if constexpr (kRational) {
      double least = std::numeric_limits<double>::infinity();
      for (int k = 0; k < size; ++k)
        least = std::min(least, (n[k] - rounding) / d[k]);
      return least;
    } else {
      (void)d;
      return smallest_of(n, size) - rounding;
    }
  };
  const double s_cuts[4] = {0.0, box.s0, box.s1, 1.0};
  const double t_cuts[4] = {0.0, box.t0, box.t1, 1.0};
  for (int g = 0; g < kGrids; ++g) {
    std::copy(full[g], full[g] + size, column[g][0]);
    cut_in_three(column[g], rows, cols, box.s0, box.s1);
  }
  double bound = target_sq;
  for (int a = 0; a < 3; ++a) {
    const double s0 = s_cuts[a], s1 = s_cuts[a + 1];
    if (!(s1 > s0)) continue;
    // A column beside N whose every coefficient (ratio) is at least the bound so far cannot lower
    // it: its tiles' coefficients are convex combinations of its own. On a box that spans several
    // patches the columns beyond it mostly lie farther than the target.
    if (a != 1 && smallest(column[0][a], column[kGrids - 1][a]) >= bound) continue;
    // The column's tiles, transposed (cols x rows, t along rows): the smallest coefficient
    // does not change.
    for (int g = 0; g < kGrids; ++g) {
      transpose(column[g][a], tile[g][0], rows, cols);
      cut_in_three(tile[g], cols, rows, box.t0, box.t1);
    }
    for (int b = 0; b < 3; ++b) {
      if (a == 1 && b == 1) continue;
      const double t0 = t_cuts[b], t1 = t_cuts[b + 1];
      if (!(t1 > t0)) continue;
      double value = smallest(tile[0][b], tile[kGrids - 1][b]);
      if (value < bound) {
        const bool along_s = a == 1 || (b != 1 && s1 - s0 >= t1 - t0);
        for (int g = 0; g < kGrids; ++g) {
          // Transposed: s runs along the tile's columns.
          if (along_s) {
            split_cols(tile[g][b], half[g], cols, rows);
          } else {
            split_rows(tile[g][b], half[g], cols, rows);
          }
        }
        value = std::min(smallest(tile[0][b], tile[kGrids - 1][b]),
                         smallest(half[0], half[kGrids - 1]));
      }
      bound = std::min(bound, value);
    }
  }
  return std::max(bound, 0.0);
}

// Feet on the patch's own edge or corner (points beyond the surface's boundary): F need not be
// convex around them. Instead F strictly increasing away from that edge on the box (first
// differences of one sign) and, along the edge, strictly convex (second differences of the edge's
// row) put the box's minimum on the edge, where it is unique; at a corner F increasing in both
// directions puts it at the corner. Projected Newton's only KKT point on the box is then that
// minimum. The largest radius for which this holds for every q within it of the anchor (first
// and second differences move by at most 2 r times those of E, scaled by the box's widths);
// 0 if it does not hold at the anchor.
double edge_radius(const double* n, int rows, int cols, int s_edge, int t_edge, double e_s,
                   double e_t, double e_ss, double e_tt, double r_max) {
  double radius = r_max;
  const auto limit = [&](double least, double e, double scale) {
    // least - 2 r e > 1e-12 scale (rounding) for r < radius.
    const double slack = least - 1e-12 * scale;
    if (!(slack > 0.0)) return false;
    if (e > 0.0) radius = std::min(radius, slack / (2.0 * e));
    return true;
  };
  double scale = 0.0;
  for (int k = 0; k < rows * cols; ++k)
    scale = std::max(scale, std::abs(n[k]));
  const auto at = [&](int i, int j) { return n[i * cols + j]; };
  if (s_edge != 0) {  // +1: F increases with s (edge s = 0); -1: decreases (edge s = 1)
    double least = std::numeric_limits<double>::infinity();
    for (int i = 0; i + 1 < rows; ++i) {
      for (int j = 0; j < cols; ++j)
        least = std::min(least, s_edge * (at(i + 1, j) - at(i, j)));
    }
    if (!limit(least, e_s, scale)) return 0.0;
  }
  if (t_edge != 0) {
    double least = std::numeric_limits<double>::infinity();
    for (int i = 0; i < rows; ++i) {
      for (int j = 0; j + 1 < cols; ++j)
        least = std::min(least, t_edge * (at(i, j + 1) - at(i, j)));
    }
    if (!limit(least, e_t, scale)) return 0.0;
  }
  if (s_edge != 0 && t_edge == 0) {  // convex in t along the edge row
    const int i = s_edge > 0 ? 0 : rows - 1;
    double least = std::numeric_limits<double>::infinity();
    for (int j = 0; j + 2 < cols; ++j)
      least = std::min(least, at(i, j + 2) - 2.0 * at(i, j + 1) + at(i, j));
    if (!limit(least, e_tt, scale)) return 0.0;
  }
  if (t_edge != 0 && s_edge == 0) {  // convex in s along the edge column
    const int j = t_edge > 0 ? 0 : cols - 1;
    double least = std::numeric_limits<double>::infinity();
    for (int i = 0; i + 2 < rows; ++i)
      least = std::min(least, at(i + 2, j) - 2.0 * at(i + 1, j) + at(i, j));
    if (!limit(least, e_ss, scale)) return 0.0;
  }
  return radius;
}

// The float box [center - h, center + h] clipped to [lo_limit, hi_limit] (integers), rounded
// outward so it holds center.
void float_range(double center, double h, float& lo, float& hi, double lo_limit = 0.0,
                 double hi_limit = 1.0) {
  lo = static_cast<float>(std::max(lo_limit, center - h));
  hi = static_cast<float>(std::min(hi_limit, center + h));
  if (static_cast<double>(lo) > center) lo = std::nextafter(lo, static_cast<float>(lo_limit));
  if (static_cast<double>(hi) < center) hi = std::nextafter(hi, static_cast<float>(hi_limit));
  lo = std::max(lo, static_cast<float>(lo_limit));
  hi = std::min(hi, static_cast<float>(hi_limit));
}

// The boxes certify_patch tries, as half-widths about the foot: the wider side 1/4 and 1/10 of
// P; on a trimmed face, where only a smaller box may fit in the region, then the size a
// certificate needs (the disc of surface points that may come within d + 2 r_max of a, about the
// foot, if the surface curves away no faster than its tangent plane: sqrt((d + 2 r_max)^2 - d^2),
// half as wide again) and its halves, down to an eighth, the wider side at most 1/10 of P.
// Every box is as wide in space along s as along t (h_s |S_s| = h_t |S_t| at the foot, the ratio
// kept within 1/32): on a long thin patch (a fillet's strip) a box square in P's parameters is
// several times longer in space than wide, and the tiles beside it across its long side reach
// back under the foot: their Bernstein bounds dip below zero and leave no clearance.
struct Half {
  double s, t;
};
int candidate_halves(const PreparedPatch& pp, double s, double t, double d, double r_max,
                     bool trimmed, Half* halves) {
  Vec3 der[6];
  pp.patch.derivatives(s, t, der);
  const double ls = der[1].norm(), lt = der[2].norm();
  // h_t / h_s for a box square in space (1 where a tangent vanishes: a pole).
  constexpr double kMaxAspect = 32.0;
  const double aspect = ls > 0.0 && lt > 0.0 && std::isfinite(ls / lt)
                            ? std::clamp(ls / lt, 1.0 / kMaxAspect, kMaxAspect)
                            : 1.0;
  // The box whose wider side is `widest`.
  const auto square = [aspect](double widest) {
    return aspect >= 1.0 ? Half{widest / aspect, widest} : Half{widest, widest * aspect};
  };
  int count = 0;
  halves[count++] = square(0.25);
  halves[count++] = square(0.1);
  if (trimmed) {
    const double disc = 1.5 * std::sqrt(4.0 * r_max * (d + r_max));
    // The needed box's wider side in P's units (along the shorter tangent), at most 1/10.
    const double shorter = std::min(ls, lt);
    const double need = shorter > 0.0 ? std::min(disc / shorter, 0.1) : 0.1;
    for (const double k : {1.0, 0.5, 0.25, 0.125})
      halves[count++] = square(k * need);
  }
  return count;
}
constexpr int kMaxHalves = 6;

// rational_box_differences (warm_certificate.hpp) on grids the caller provides: ep, E' by
// component; re and rd, scratch for the restricted grids.
BoxDifferences box_differences(const double* const ep[3], const double* dd, int rows, int cols,
                               const LocalBox& box, double* re[3], double* rd, double* work,
                               double* strip) {
  const int size = rows * cols;
  for (int c = 0; c < 3; ++c)
    restrict_grid(ep[c], re[c], work, strip, rows, cols, box);
  restrict_grid(dd, rd, work, strip, rows, cols, box);
  double e_largest = 0.0, d_largest = 0.0;
  for (int k = 0; k < size; ++k) {
    e_largest = std::max(e_largest, std::abs(re[0][k]) + std::abs(re[1][k]) + std::abs(re[2][k]));
    d_largest = std::max(d_largest, std::abs(rd[k]));
  }
  BoxDifferences b;
  // Second difference at (i, j) with steps (di1, dj1) and (di2, dj2): x(i + di1 + di2, j + dj1 +
  // dj2) - x(i + di1, j + dj1) - x(i + di2, j + dj2) + x(i, j).
  const auto difference = [&](const double* x, int i, int j, int di1, int dj1, int di2, int dj2) {
    return x[(i + di1 + di2) * cols + j + dj1 + dj2] - x[(i + di1) * cols + j + dj1] -
           x[(i + di2) * cols + j + dj2] + x[i * cols + j];
  };
  const auto vector_norm = [&](int i, int j, int di1, int dj1, int di2, int dj2) {
    const double x = difference(re[0], i, j, di1, dj1, di2, dj2);
    const double y = difference(re[1], i, j, di1, dj1, di2, dj2);
    const double z = difference(re[2], i, j, di1, dj1, di2, dj2);
    return std::sqrt(x * x + y * y + z * z);
  };
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      if (i + 2 < rows) {
        b.e_ss = std::max(b.e_ss, vector_norm(i, j, 1, 0, 1, 0));
        b.d_ss = std::max(b.d_ss, std::abs(difference(rd, i, j, 1, 0, 1, 0)));
      }
      if (j + 2 < cols) {
        b.e_tt = std::max(b.e_tt, vector_norm(i, j, 0, 1, 0, 1));
        b.d_tt = std::max(b.d_tt, std::abs(difference(rd, i, j, 0, 1, 0, 1)));
      }
      if (i + 1 < rows && j + 1 < cols) {
        b.e_st = std::max(b.e_st, vector_norm(i, j, 1, 0, 0, 1));
        b.d_st = std::max(b.d_st, std::abs(difference(rd, i, j, 1, 0, 0, 1)));
      }
    }
  }
  const double e_round = 1e-12 * e_largest, d_round = 1e-12 * d_largest;
  b.e_ss += e_round;
  b.e_tt += e_round;
  b.e_st += e_round;
  b.d_ss += d_round;
  b.d_tt += d_round;
  b.d_st += d_round;
  return b;
}

// E' = E - (a - o) D by component, into ep.
void e_prime(const PreparedPatch& pp, const Vec3& a, double* const ep[3]) {
  const Vec3 ao = a - pp.origin;
  const int size = pp.rows * pp.cols;
  for (int k = 0; k < size; ++k) {
    for (int c = 0; c < 3; ++c)
      ep[c][k] = pp.e[static_cast<std::size_t>(k)][c] - ao[c] * pp.d[static_cast<std::size_t>(k)];
  }
}

// certify_patch for a rational patch, F = N / D. For q = a + delta (|delta| <= r) and a value m,
// G = N_q - m D = H + k D - 2 delta . E' with H = N_a - d^2 D, E' = E - (a - o) D (o the
// patch's origin) and k = d^2 - m + |delta|^2. A query's proof (newton_on_certificate) has m, its
// minimum on N, within [(d - r)^2, (d + 2 r)^2] (no model point is nearer to q than d - r, and
// the proof needs sqrt(m) <= clearance <= d + 2 r), so |k| <= 4 r (d + r). If every such G is
// strictly convex on N, a KKT point x* of F on N with F(x*) = m is one of G_m (grad F = grad G_m
// / D there), hence G_m's minimum, 0: F >= m on N (f_derivatives' argument). The test: H's
// second-derivative ranges on N widened by 2 r |E'| + 4 r (d + r) |D| differences: the whole
// patch's scaled by N's widths, and where that falls short of the cap those of E' and D
// restricted to N (rational_box_differences). Interior feet only (no edge proof).
PatchCertificate certify_rational_patch(const PreparedPatch& pp, const Vec3& a, double s, double t,
                                        double d, double r_max, SurfaceScratch& scratch,
                                        const TrimRegion* region) {
  PatchCertificate c;
  if (!(s > 0.0 && s < 1.0 && t > 0.0 && t < 1.0)) return c;
  const int rows = pp.rows, cols = pp.cols, size = rows * cols;
  double* full = scratch.grids.data();
  double* h = full + SurfaceScratch::kGridCapacity;
  double* grid = h + SurfaceScratch::kGridCapacity;
  double* strip = grid + SurfaceScratch::kGridCapacity;
  double* work = strip + SurfaceScratch::kGridCapacity;
  constexpr int kCap = SurfaceScratch::kGridCapacity;
  const double* dd = pp.d.data();
  pp.numerator(a, full);
  const double d2 = d * d;
  for (int k = 0; k < size; ++k)
    h[k] = full[k] - d2 * dd[k];
  const double ao = (a - pp.origin).norm();
  // E' = E - (a - o) D by component, and scratch for the boxes' restricted grids.
  double* ep[3] = {work + kCap, work + 2 * kCap, work + 3 * kCap};
  double* re[3] = {work + 4 * kCap, work + 5 * kCap, work + 6 * kCap};
  double* rd = work + 7 * kCap;
  double* tiles = rd + kCap;  // tiled_lower_bound's 16
  bool have_ep = false;       // E' is formed the first time the quick widening falls short
  // The rounding of d^2 against the true F_a(foot) (relative), on k's bound.
  const double fixed = 1e-12 * (d + r_max) * (d + r_max);
  // The quick widening first: the whole patch's differences scaled by the box's widths, with
  // |a - o| D bounding a's part (O(1)); when it already proves the cap, N's own grids (four
  // restrictions) cannot prove more. Both bound the same differences, so the larger radius holds.
  const auto quick = [&](double ws, double wt) {
    const double ss = ws * ws, tt = wt * wt, st = ws * wt;
    return Widening{ss * (2.0 * (pp.e_ss + ao * pp.d_ss) + 4.0 * d * pp.d_ss),
                    tt * (2.0 * (pp.e_tt + ao * pp.d_tt) + 4.0 * d * pp.d_tt),
                    st * (2.0 * (pp.e_st + ao * pp.d_st) + 4.0 * d * pp.d_st),
                    ss * 4.0 * pp.d_ss,
                    tt * 4.0 * pp.d_tt,
                    st * 4.0 * pp.d_st,
                    ss * fixed * pp.d_ss,
                    tt * fixed * pp.d_tt,
                    st * fixed * pp.d_st};
  };
  const auto widening = [&](const LocalBox& box) {
    if (!have_ep) {
      e_prime(pp, a, ep);
      have_ep = true;
    }
    const BoxDifferences b = box_differences(ep, dd, rows, cols, box, re, rd, work, strip);
    return Widening{2.0 * b.e_ss + 4.0 * d * b.d_ss,
                    2.0 * b.e_tt + 4.0 * d * b.d_tt,
                    2.0 * b.e_st + 4.0 * d * b.d_st,
                    4.0 * b.d_ss,
                    4.0 * b.d_tt,
                    4.0 * b.d_st,
                    fixed * b.d_ss,
                    fixed * b.d_tt,
                    fixed * b.d_st};
  };
  const auto radius_on = [&](const double* g, const LocalBox& box) {
    const double r = grid_convexity_radius_widened(g, rows, cols,
                                                   quick(box.s1 - box.s0, box.t1 - box.t0), r_max);
    if (r >= r_max) return r;
    return std::max(r, grid_convexity_radius_widened(g, rows, cols, widening(box), r_max));
  };
  if (box_in_region(region, pp.patch, 0.0, 1.0, 0.0, 1.0)) {
    c.radius = radius_on(h, {0.0, 1.0, 0.0, 1.0});
    if (c.radius > 0.0) {
      c.outside_sq = std::numeric_limits<double>::infinity();
      return c;
    }
  }
  const double reach = pp.sphere.radius + ao;
  const double rounding = 1e-14 * reach * reach;
  Half halves[kMaxHalves];
  const int count = candidate_halves(pp, s, t, d, r_max, region != nullptr, halves);
  for (int n = 0; n < count; ++n) {
    float_range(s, halves[n].s, c.s0, c.s1);
    float_range(t, halves[n].t, c.t0, c.t1);
    const double ws = double(c.s1) - c.s0, wt = double(c.t1) - c.t0;
    if (!(ws > 0.0) || !(wt > 0.0)) continue;
    if (!box_in_region(region, pp.patch, c.s0, c.s1, c.t0, c.t1)) continue;
    restrict_grid(h, grid, work, strip, rows, cols, {c.s0, c.s1, c.t0, c.t1});
    c.radius = radius_on(grid, {c.s0, c.s1, c.t0, c.t1});
    if (c.radius > 0.0) {
      const double target = (d + 2.0 * c.radius) * (d + 2.0 * c.radius);
      c.outside_sq = tiled_lower_bound<true>(full, dd, rows, cols, {c.s0, c.s1, c.t0, c.t1}, target,
                                             rounding, tiles);
      return c;
    }
  }
  return PatchCertificate{};
}

}  // namespace

BoxDifferences rational_box_differences(const PreparedPatch& pp, const Vec3& a, double s0,
                                        double s1, double t0, double t1, SurfaceScratch& scratch) {
  double* g = scratch.grids.data();
  constexpr int kCap = SurfaceScratch::kGridCapacity;
  double* ep[3] = {g, g + kCap, g + 2 * kCap};
  double* re[3] = {g + 3 * kCap, g + 4 * kCap, g + 5 * kCap};
  e_prime(pp, a, ep);
  return box_differences(ep, pp.d.data(), pp.rows, pp.cols, {s0, s1, t0, t1}, re, g + 6 * kCap,
                         g + 7 * kCap, g + 8 * kCap);
}

bool box_in_region(const TrimRegion* region, const BezierPatch& bp, double s0, double s1, double t0,
                   double t1) {
  if (region == nullptr) return true;
  // Newton's points in the box map to (u, v) = to_parent(s, t), which rounds: the box is
  // widened by far more than that rounding.
  const auto widened = [](const ParamInterval& p, double a, double b, double& lo, double& hi) {
    const double slack = 1e-12 * (std::abs(p.lo) + std::abs(p.hi));
    lo = p.to_parent(a) - slack;
    hi = p.to_parent(b) + slack;
  };
  double u0, u1, v0, v1;
  widened(bp.param_u, s0, s1, u0, u1);
  widened(bp.param_v, t0, t1, v0, v1);
  return region->classify(u0, u1, v0, v1) == RegionClass::inside;
}

PatchCertificate certify_patch(const PreparedPatch& pp, const Vec3& a, double s, double t, double d,
                               double r_max, SurfaceScratch& scratch, const TrimRegion* region) {
  PatchCertificate c;
  if (!a.allFinite() || !(r_max > 0.0)) return c;
  if (pp.rational) return certify_rational_patch(pp, a, s, t, d, r_max, scratch, region);
  const int rows = pp.rows, cols = pp.cols;
  double* full = scratch.grids.data();
  double* grid = full + SurfaceScratch::kGridCapacity;
  double* strip = grid + SurfaceScratch::kGridCapacity;
  double* work = strip + SurfaceScratch::kGridCapacity;
  pp.numerator(a, full);
  if (box_in_region(region, pp.patch, 0.0, 1.0, 0.0, 1.0)) {
    c.radius = grid_convexity_radius(full, rows, cols, pp.e_ss, pp.e_tt, pp.e_st, r_max);
    if (c.radius > 0.0) {
      c.outside_sq = std::numeric_limits<double>::infinity();
      return c;
    }
  }
  // The same rounding allowance as the clipping's (coefficients carry ~eps reach^2).
  const double reach = pp.sphere.radius + (a - pp.origin).norm();
  const double rounding = 1e-14 * reach * reach;
  // A foot on the patch's edge: which edge (s = 0 edge: F must increase with s, and so on).
  const int s_edge = s <= 0.0 ? 1 : (s >= 1.0 ? -1 : 0);
  const int t_edge = t <= 0.0 ? 1 : (t >= 1.0 ? -1 : 0);
  // All of P first for a foot on its edge, then candidate_halves.
  Half halves[kMaxHalves + 1] = {{1.0, 1.0}};
  const int count = 1 + candidate_halves(pp, s, t, d, r_max, region != nullptr, halves + 1);
  for (int n = 0; n < count; ++n) {
    const double h = halves[n].s;
    if (h == 1.0 && s_edge == 0 && t_edge == 0) continue;  // all of P: tested above
    float_range(s, halves[n].s, c.s0, c.s1);
    float_range(t, halves[n].t, c.t0, c.t1);
    const double ws = double(c.s1) - c.s0, wt = double(c.t1) - c.t0;
    if (!(ws > 0.0) || !(wt > 0.0)) continue;
    if (!box_in_region(region, pp.patch, c.s0, c.s1, c.t0, c.t1)) continue;
    restrict_grid(full, grid, work, strip, rows, cols, {c.s0, c.s1, c.t0, c.t1});
    // E restricted to the box: its first and second differences are those of the derivatives'
    // coefficients scaled by the box's widths, convex combinations of the whole patch's.
    c.radius = n == 0 ? 0.0
                      : grid_convexity_radius(grid, rows, cols, pp.e_ss * ws * ws,
                                              pp.e_tt * wt * wt, pp.e_st * ws * wt, r_max);
    if (!(c.radius > 0.0) && (s_edge != 0 || t_edge != 0)) {
      c.radius = edge_radius(grid, rows, cols, s_edge, t_edge, pp.e_s * ws, pp.e_t * wt,
                             pp.e_ss * ws * ws, pp.e_tt * wt * wt, r_max);
    }
    if (c.radius > 0.0) {
      const double target = (d + 2.0 * c.radius) * (d + 2.0 * c.radius);
      c.outside_sq =
          tiled_lower_bound<false>(full, nullptr, rows, cols, {c.s0, c.s1, c.t0, c.t1}, target,
                                   rounding, work + SurfaceScratch::kGridCapacity);
      return c;
    }
  }
  c = PatchCertificate{};
  return c;
}

double newton_on_certificate_box(const PreparedModel& model, std::int64_t anchor_patch, float s0,
                                 float s1, float t0, float t1, const Vec3& p, std::int64_t& patch,
                                 double& s, double& t, Vec3& foot, Vec3& normal, bool& stationary,
                                 bool predict) {
  stationary = false;
  const int surface = model.patch_surface(static_cast<std::size_t>(anchor_patch));
  const PreparedModel::SpanCell cell = model.patch_span(static_cast<std::size_t>(anchor_patch));
  // The tangent plane's least-squares step from the foot f = S(s, t) towards p (whatever point f
  // was the foot of, it lay on f's normal, so p - f has the same tangential part), in the anchor
  // patch's grid units (N's coordinates), kept in N. Only the start changes, not the proof. It
  // replaces the Newton's first full evaluation with a first-derivative one, so only on a box
  // that spans patches (within one, Newton's own first step does as well; the blade's 5 cm strips
  // are where it pays), where the degrees have that kernel, and on polynomial patches (measured:
  // on NIST's rational cylinders the quotient rule made it cost more than it saved).
  const bool spans = s0 < 0.0f || s1 > 1.0f || t0 < 0.0f || t1 > 1.0f;
  Vec3 d[3];
  if (predict && spans && patch == anchor_patch &&
      model.patch(static_cast<std::size_t>(patch)).unit_weights &&
      patch_tangents(model.patch(static_cast<std::size_t>(patch)), s, t, d)) {
    const Vec3 delta = p - d[0];
    const double a = d[1].squaredNorm(), b = d[1].dot(d[2]), c = d[2].squaredNorm();
    const double det = a * c - b * b;
    if (det > 1e-12 * a * c) {
      const double rs = d[1].dot(delta), rt = d[2].dot(delta);
      const double ps = std::clamp(s + (c * rs - b * rt) / det, double(s0), double(s1));
      const double pt = std::clamp(t + (a * rt - b * rs) / det, double(t0), double(t1));
      // The piece holding it; on a side between two, the one inside N.
      int pi = static_cast<int>(std::floor(ps)), pj = static_cast<int>(std::floor(pt));
      if (pi >= s1) --pi;
      if (pj >= t1) --pj;
      LocalBox box;
      const std::int64_t k = model.patch_at(surface, cell.a + pi, cell.b + pj);
      if (k >= 0 && span_piece(s0, s1, t0, t1, pi, pj, box.s0, box.s1, box.t0, box.t1)) {
        patch = k;
        s = std::clamp(ps - pi, box.s0, box.s1);
        t = std::clamp(pt - pj, box.t0, box.t1);
      }
    }
  }
  const PreparedModel::SpanCell here = model.patch_span(static_cast<std::size_t>(patch));
  int i = here.a - cell.a, j = here.b - cell.b;
  LocalBox box;
  if (model.patch_surface(static_cast<std::size_t>(patch)) != surface ||
      !span_piece(s0, s1, t0, t1, i, j, box.s0, box.s1, box.t0, box.t1)) {
    return std::numeric_limits<double>::infinity();
  }
  bool settled = false;
  double f = newton_to_proven_point(model.patch(static_cast<std::size_t>(patch)), p, box.s0, box.s1,
                                    box.t0, box.t1, s, t, foot, &normal, &settled);
  if (!settled) return f;
  // A side counts as touched within 1e-9 of the piece (Newton settles to ~1e-10 of it).
  constexpr double kTouch = 1e-9;
  // Enough moves to cross N from corner to corner (2 kReach + 1 pieces a side), and more.
  for (int moves = 0; moves < 4 * SpanCertificate::kReach + 4; ++moves) {
    // The neighbouring pieces that touch the point: across a side N continues over.
    int di = 0, dj = 0;
    const auto overlaps = [&](int pi, int pj) {
      LocalBox unused;
      return span_piece(s0, s1, t0, t1, pi, pj, unused.s0, unused.s1, unused.t0, unused.t1);
    };
    if (s <= box.s0 + kTouch && box.s0 == 0.0 && overlaps(i - 1, j)) {
      di = -1;
    } else if (s >= box.s1 - kTouch && box.s1 == 1.0 && overlaps(i + 1, j)) {
      di = 1;
    }
    if (t <= box.t0 + kTouch && box.t0 == 0.0 && overlaps(i, j - 1)) {
      dj = -1;
    } else if (t >= box.t1 - kTouch && box.t1 == 1.0 && overlaps(i, j + 1)) {
      dj = 1;
    }
    if (di == 0 && dj == 0) {
      stationary = true;
      return f;
    }
    bool improved = false;
    // Across one side, or at a corner across either side or diagonally.
    const int steps[3][2] = {{di, dj}, {di, 0}, {0, dj}};
    const int count = di != 0 && dj != 0 ? 3 : 1;
    for (int m = 0; m < count; ++m) {
      const int* step = steps[m];
      LocalBox next;
      if (!span_piece(s0, s1, t0, t1, i + step[0], j + step[1], next.s0, next.s1, next.t0,
                      next.t1)) {
        continue;  // a corner piece outside N (N's corner is there)
      }
      const std::int64_t k = model.patch_at(surface, cell.a + i + step[0], cell.b + j + step[1]);
      // The same point from the neighbour's side: local 1 becomes 0 across a side, and so on.
      double ns = step[0] < 0 ? 1.0 : (step[0] > 0 ? 0.0 : s);
      double nt = step[1] < 0 ? 1.0 : (step[1] > 0 ? 0.0 : t);
      Vec3 nfoot, nnormal;
      bool ok = false;
      const double nf =
          newton_to_proven_point(model.patch(static_cast<std::size_t>(k)), p, next.s0, next.s1,
                                 next.t0, next.t1, ns, nt, nfoot, &nnormal, &ok);
      if (!ok) return f;
      if (nf < f) {
        f = nf;
        s = ns;
        t = nt;
        foot = nfoot;
        normal = nnormal;
        patch = k;
        i += step[0];
        j += step[1];
        box = next;
        improved = true;
        break;
      }
    }
    if (!improved) {
      stationary = true;
      return f;
    }
  }
  return f;
}

SpanCertificate certify_span(const PreparedModel& model, std::size_t patch, const Vec3& a, double s,
                             double t, double d, double r_max, double half_s, double half_t,
                             double floor, int reach, SurfaceScratch& scratch) {
  SpanCertificate c;
  const int surface = model.patch_surface(patch);
  if (!a.allFinite() || !(r_max > 0.0) || !model.surface_c1(surface)) return c;
  const PreparedModel::SpanCell at = model.patch_span(patch);
  reach = std::clamp(reach, 1, SpanCertificate::kReach);
  // N's limits: the surface's grid, and at most `reach` patches beyond P on every side.
  const auto exists = [&](int i, int j) {
    return model.patch_at(surface, at.a + i, at.b + j) >= 0;
  };
  // How many patches follow P in direction (di, dj) before the grid ends, up to `reach`.
  const auto run = [&](int di, int dj) {
    int n = 0;
    while (n < reach && exists((n + 1) * di, (n + 1) * dj))
      ++n;
    return static_cast<double>(n);
  };
  const double s_lo = -run(-1, 0), s_hi = 1.0 + run(1, 0);
  const double t_lo = -run(0, -1), t_hi = 1.0 + run(0, 1);
  float_range(s, half_s, c.s0, c.s1, s_lo, s_hi);
  float_range(t, half_t, c.t0, c.t1, t_lo, t_hi);
  // A foot on the surface's own edge or corner (a patch edge shared with a neighbour is inside N).
  const int s_edge = s <= 0.0 && s_lo == 0.0 ? 1 : (s >= 1.0 && s_hi == 1.0 ? -1 : 0);
  const int t_edge = t <= 0.0 && t_lo == 0.0 ? 1 : (t >= 1.0 && t_hi == 1.0 ? -1 : 0);
  double* full = scratch.grids.data();
  double* grid = full + SurfaceScratch::kGridCapacity;
  double* strip = grid + SurfaceScratch::kGridCapacity;
  double* work = strip + SurfaceScratch::kGridCapacity;
  struct Piece {
    const PreparedPatch* pp;
    LocalBox box;
  };
  Piece pieces[SpanCertificate::kMaxPatches];
  for (int i = -reach; i <= reach; ++i) {
    for (int j = -reach; j <= reach; ++j) {
      LocalBox box;
      if (!span_piece(c.s0, c.s1, c.t0, c.t1, i, j, box.s0, box.s1, box.t0, box.t1)) continue;
      const std::int64_t k = model.patch_at(surface, at.a + i, at.b + j);
      if (k < 0 || model.patch(static_cast<std::size_t>(k)).rational ||
          !box_in_region(model.surface_region(surface),
                         model.patch(static_cast<std::size_t>(k)).patch, box.s0, box.s1, box.t0,
                         box.t1)) {
        return SpanCertificate{};
      }
      pieces[c.count] = {&model.patch(static_cast<std::size_t>(k)), box};
      c.patches[c.count++] = k;
    }
  }
  // Each piece's grid of F (its numerator), made once: the convexity proof (once or twice) and
  // the bound beside N read it. In the scratch's grids after the ones the proofs use.
  constexpr int kFirstPieceGrid = 12;
  static_assert((kFirstPieceGrid + SpanCertificate::kMaxPatches) * SurfaceScratch::kGridCapacity <=
                (SurfaceScratch::kStackCapacity + 1) * 2 * SurfaceScratch::kGridCapacity);
  bool made[SpanCertificate::kMaxPatches] = {};
  const auto numerator_of = [&](int k) {
    double* f = scratch.grids.data() + (kFirstPieceGrid + k) * SurfaceScratch::kGridCapacity;
    if (!made[k]) {
      pieces[k].pp->numerator(a, f);
      made[k] = true;
    }
    return static_cast<const double*>(f);
  };
  // Every piece strictly convex, or (an edge foot) every piece increasing away from the edge: the
  // same kind of proof on all of them, so that they add up to one on N.
  const auto radius_over_pieces = [&](bool edge) {
    double radius = r_max;
    for (int k = 0; k < c.count && radius > floor; ++k) {
      const PreparedPatch& pp = *pieces[k].pp;
      const LocalBox& b = pieces[k].box;
      const double ws = b.s1 - b.s0, wt = b.t1 - b.t0;
      const double* f = numerator_of(k);
      // F_q strictly convex on all of the patch for every q within `radius` is so on any piece
      // of it (the piece's second differences are convex combinations of the patch's, scaled
      // by its widths, as is the widening): the piece's own test, which needs its grid
      // restricted (the most costly step here on the IEA blade's degree-(3, 8) strips), only
      // where the patch's does not hold. On a piece that is the whole patch the two are one.
      if (!edge && !b.whole() &&
          grid_convexity_radius(f, pp.rows, pp.cols, pp.e_ss, pp.e_tt, pp.e_st, radius) >= radius) {
        continue;
      }
      restrict_grid(f, grid, work, strip, pp.rows, pp.cols, b);
      radius = edge ? edge_radius(grid, pp.rows, pp.cols, s_edge, t_edge, pp.e_s * ws, pp.e_t * wt,
                                  pp.e_ss * ws * ws, pp.e_tt * wt * wt, radius)
                    : grid_convexity_radius(grid, pp.rows, pp.cols, pp.e_ss * ws * ws,
                                            pp.e_tt * wt * wt, pp.e_st * ws * wt, radius);
    }
    return radius;
  };
  c.radius = radius_over_pieces(false);
  if (!(c.radius > 0.0) && (s_edge != 0 || t_edge != 0)) c.radius = radius_over_pieces(true);
  if (!(c.radius > floor)) return SpanCertificate{};
  // The overlapped patches outside N: their tiles around the piece, as certify_patch bounds P's.
  const double target = (d + 2.0 * c.radius) * (d + 2.0 * c.radius);
  c.outside_sq = target;
  for (int k = 0; k < c.count; ++k) {
    const PreparedPatch& pp = *pieces[k].pp;
    const LocalBox& b = pieces[k].box;
    if (b.whole()) continue;  // all inside N
    const double reach = pp.sphere.radius + (a - pp.origin).norm();
    c.outside_sq =
        std::min(c.outside_sq, tiled_lower_bound<false>(numerator_of(k), nullptr, pp.rows, pp.cols,
                                                        b, target, 1e-14 * reach * reach,
                                                        work + SurfaceScratch::kGridCapacity));
    if (!(c.outside_sq > (d + 2.0 * floor) * (d + 2.0 * floor))) return SpanCertificate{};
  }
  return c;
}

}  // namespace nurbsreg::engine
