#include "proofs/reach_bounds.hpp"
#include "nurbsreg/engine/cancellation.hpp"

// Reach bounds. For a foot f of the model M and a unit direction v of M's normal cone at f, the
// point q = f + d v has f as its closest point on M exactly when the open ball B(f + d v, d)
// holds no point of M, and that holds for every d up to the cut distance
//   t_cut(f, v) = inf over x in M with v.(x - f) > 0 of |x - f|^2 / (2 v.(x - f))
// (|x - (f + d v)|^2 - d^2 = |x - f|^2 - 2 d v.(x - f)). A lower bound of t_cut over every foot
// of a cell of a patch and every v of one kind (the normal's two sides, the boundary's cone) is
// what a cell stores. It is made of two parts:
//
//  - x near f: N, the cell grown by an eighth of a patch (at least half a cell) on every side
//    (within the surface's domain, and within the patch unless the surface is C1 across patch
//    edges). For f = S(b) and x = S(a) in N, with Delta = a - b:
//      |x - f| >= (sigma - E) |Delta|, sigma the smallest singular value of the Jacobian J0 at
//      the cell's centre and E >= |J - J0| over N (Bézier hodograph bounds), since
//      x - f = integral of J along the segment times Delta;
//      v.(x - f) <= K |Delta|^2 / 2, K >= v.S''[Delta, Delta] / |Delta|^2 over N (for +n and -n
//      apart: the signed extremes of n0 . S'', plus the normal's spread times |S''|), since
//      v.J(b) Delta <= 0 for every v of the normal cone at f and every Delta pointing into the
//      domain (Taylor with integral remainder; S is C1 and piecewise polynomial along the
//      segment).
//    So t_cut >= (sigma - E)^2 / K for those x (no limit where K <= 0: N curves away).
//  - everything else of the model (every surface's patches, trimmed ones whole: more points only
//    lower the bound): a best-first branch and bound over pairs (a piece of the cell, a box of
//    the model), the model's hierarchy first, then Bézier sub-patches. A pair's bound is
//    min |w|^2 / (2 max v.w) over w = x - f in the difference of the two boxes (both in the
//    cell piece's own frame: tangent, tangent, normal); v.w is a convex function of w for the
//    cone's directions, so its maximum over the box is at a corner. The cone of a piece is known
//    up to eps: |v - v0| <= eps for a nominal direction v0 (Bézier bounds on S_u, S_v and
//    |a / |a| - b / |b|| <= 2 |a - b| / |b|).
// The search stops at the local part's bound: a cell's bound is the smaller of the two.

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include "bernstein/binomial_table.hpp"
#include "model/prepared_model_internals.hpp"

namespace nurbsreg::engine {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Halvings of a piece along one parameter before the search stops refining it.
constexpr int kMaxLevel = 7;
// Pairs taken from the queue per cell and side before the search settles for its current
// bound (build time: a few hundred microseconds per cell). More for the boundary cone's sectors:
// their cells are few (the surface's edges), and far points project there (on the peers
// benchmark's 49-patch panel, 8 x 8 cells a patch: 1,500 proves 2,000 more of its 100,000 points
// than 600, for 0.2 s; beyond that the local part limits them; 1,500 for the normal's sides adds
// 345 for 0.4 s).
constexpr int kBudget = 600;
constexpr int kBoundaryBudget = 1500;
constexpr std::size_t kCellBudget = 16384;
// N reaches beyond the cell on every side by an eighth of the patch, at least half a cell
// (measured best on the benchmark panels, 16 x 16, 8 x 8 and 2 x 2 cells a patch: a wider N
// weakens the local bound, a narrower one the far search's).
double margin_in_cells(int cells_per_side) {
  return std::max(0.5, cells_per_side / 8.0);
}
constexpr int kMaxPoints = (kMaxDegree + 1) * (kMaxDegree + 1);

struct Rect {
  double s0 = 0.0, s1 = 1.0, t0 = 0.0, t1 = 1.0;
};

// A copy of a patch's homogeneous control points, (p + 1) x (q + 1), row-major in u.
struct Grid {
  int p = 0, q = 0;
  std::array<Vec4, kMaxPoints> cw;
  const Vec4& at(int i, int j) const { return cw[static_cast<std::size_t>(i * (q + 1) + j)]; }
  Vec4& at(int i, int j) { return cw[static_cast<std::size_t>(i * (q + 1) + j)]; }
  Vec3 point(int i, int j) const { return at(i, j).head<3>() / at(i, j)[3]; }
};

// The grid split along u (dir 0) or v (dir 1) at tau into its parts before and after tau.
void split(const Grid& g, int dir, double tau, Grid& low, Grid& high) {
  low.p = high.p = g.p;
  low.q = high.q = g.q;
  const int stride = g.q + 1;
  if (dir == 0) {
    for (int j = 0; j <= g.q; ++j)
      de_casteljau_split(g.cw.data() + j, stride, g.p, tau, low.cw.data() + j, high.cw.data() + j,
                         stride);
  } else {
    for (int i = 0; i <= g.p; ++i)
      de_casteljau_split(g.cw.data() + i * stride, 1, g.q, tau, low.cw.data() + i * stride,
                         high.cw.data() + i * stride, 1);
  }
}

Grid restrict_to(const BezierPatch& bp, const Rect& r) {
  Grid g;
  g.p = bp.degree_u;
  g.q = bp.degree_v;
  for (int i = 0; i <= g.p; ++i)
    for (int j = 0; j <= g.q; ++j)
      g.at(i, j) = bp.at(i, j);
  // Per direction: cut at the rect's high end, then at its low end (rescaled to what is left).
  Grid low, high;
  for (int dir = 0; dir < 2; ++dir) {
    const double lo = dir == 0 ? r.s0 : r.t0, hi = dir == 0 ? r.s1 : r.t1;
    if (hi < 1.0) {
      split(g, dir, hi, low, high);
      g = low;
    }
    if (lo > 0.0) {
      split(g, dir, lo / hi, low, high);
      g = high;
    }
  }
  return g;
}

// Orthonormal frame: to(x) gives x's coordinates (tangent, tangent, normal).
struct Frame {
  Vec3 e[3] = {Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  Vec3 to(const Vec3& x) const { return {e[0].dot(x), e[1].dot(x), e[2].dot(x)}; }
};

Aabb points_box(const Vec4* cw, int count, const Frame& f) {
  Aabb box;
  for (int k = 0; k < count; ++k)
    box.extend(f.to(cw[k].head<3>() / cw[k][3]));
  return box;
}

Aabb grid_box(const Grid& g, const Frame& f) {
  return points_box(g.cw.data(), (g.p + 1) * (g.q + 1), f);
}

// The normal cone's boundary part at feet on the surface's own edge (m1 only) or corner (the
// tangential directions t with t.g1 >= 0 and t.g2 >= 0, whose extreme rays are m1 and m2), in
// the piece's frame: v = cos th nrm + sin th t, th in [0, pi]. eps bounds |v - v0| for the
// nominal v0 over the piece's feet (a corner is one point: its cone is evaluated there).
struct Cone {
  bool corner = false;
  int edge = -1;  // an edge's cone: which edge of the domain (DomainEdges order)
  Vec3 nrm = Vec3::UnitZ();
  Vec3 m1 = Vec3::Zero(), m2 = Vec3::Zero(), g1 = Vec3::Zero(), g2 = Vec3::Zero();
  double eps = 2.0;
};

// A piece of the cell (feet f), with what its pairs' bounds need.
struct FootPiece {
  Rect rect;
  int level_s = 0, level_t = 0;
  Frame frame;
  Aabb box;          // in frame
  double eps_n = 2;  // |n(f) - n0| over the piece
  int cones = 0;
  Cone cone[8];
  double len_s = 0, len_t = 0;
  // In the piece's own parameters: min n0 . N over the piece (Bézier product coefficients),
  // max |S_s|, max |S_t| (hodographs).
  double min_normal = 0, max_ss = 0, max_st = 0;
  std::int32_t child[2] = {-1, -1};  // its halves, once split (shared by all its pairs)
};

// A piece of the model outside N (points x); its control points are in Search::pool.
struct ModelPiece {
  Rect rect;
  int level_s = 0, level_t = 0;
  int p = 0, q = 0;
  std::size_t offset = 0;
  double len_s = 0, len_t = 0;
  std::int64_t child[2] = {-1, -1};  // its halves, once split (shared by all its pairs)
};

void lengths(const Grid& g, double& len_s, double& len_t) {
  len_s = (g.point(g.p, 0) - g.point(0, 0)).norm() + (g.point(g.p, g.q) - g.point(0, g.q)).norm();
  len_t = (g.point(0, g.q) - g.point(0, 0)).norm() + (g.point(g.p, g.q) - g.point(g.p, 0)).norm();
}

// Which edges of the surface's domain the rect of patch bp touches: [u lo, u hi, v lo, v hi].
struct DomainEdges {
  bool at[4] = {false, false, false, false};
};

DomainEdges touched_edges(const BezierPatch& bp, const Rect& r, const NurbsSurface& s) {
  DomainEdges e;
  e.at[0] = r.s0 == 0.0 && bp.param_u.lo <= s.domain_u().lo;
  e.at[1] = r.s1 == 1.0 && bp.param_u.hi >= s.domain_u().hi;
  e.at[2] = r.t0 == 0.0 && bp.param_v.lo <= s.domain_v().lo;
  e.at[3] = r.t1 == 1.0 && bp.param_v.hi >= s.domain_v().hi;
  return e;
}

// Up to 2 kMaxDegree (Bézier products).
constexpr BinomialTable<2 * kMaxDegree> kBinomials;

// Bound of |x / |x| - x0| over the convex hull of the vectors `c` (a Bézier vector function's
// control points), x0 unit: |x_perp| <= max |c_perp| and x . x0 >= min c . x0, so the angle is
// at most atan(max perp / min parallel) <= max perp / min parallel; 2 (no bound) when the
// parallel part is not positive.
double direction_spread(const Vec3* c, int count, const Vec3& x0) {
  double perp = 0.0, par = std::numeric_limits<double>::infinity();
  for (int k = 0; k < count; ++k) {
    const double along = c[k].dot(x0);
    par = std::min(par, along);
    perp = std::max(perp, (c[k] - along * x0).norm());
  }
  return par > 0.0 ? std::min(2.0, perp / par) : 2.0;
}

// Control points (2p - 1, 2q - 1) of N = S_s x S_t for the polynomial grid g (Bézier product:
// the coefficient of B_k B_l gathers C(p-1, i1) C(p, i2) / C(2p-1, k) (the same in t) times
// S_s's (i1, j1) x S_t's (i2, j2) over i1 + i2 = k, j1 + j2 = l).
int normal_control_points(const Grid& g, Vec3* out) {
  const int p = g.p, q = g.q;
  const int nu = 2 * p - 1, nv = 2 * q - 1;
  const auto& c = kBinomials.c;
  std::array<Vec3, kMaxPoints> pts, su, sv;
  for (int i = 0; i <= p; ++i)
    for (int j = 0; j <= q; ++j)
      pts[static_cast<std::size_t>(i * (q + 1) + j)] = g.point(i, j);
  const auto at = [&](int i, int j) -> const Vec3& {
    return pts[static_cast<std::size_t>(i * (q + 1) + j)];
  };
  for (int i = 0; i < p; ++i)  // S_s: (p - 1, q), binomial weights folded in
    for (int j = 0; j <= q; ++j)
      su[static_cast<std::size_t>(i * (q + 1) + j)] =
          (p * c[p - 1][i] * c[q][j]) * (at(i + 1, j) - at(i, j));
  for (int i = 0; i <= p; ++i)  // S_t: (p, q - 1)
    for (int j = 0; j < q; ++j)
      sv[static_cast<std::size_t>(i * q + j)] =
          (q * c[p][i] * c[q - 1][j]) * (at(i, j + 1) - at(i, j));
  for (int k = 0; k <= nu; ++k)
    for (int l = 0; l <= nv; ++l)
      out[k * (nv + 1) + l] = Vec3::Zero();
  for (int i1 = 0; i1 < p; ++i1)
    for (int j1 = 0; j1 <= q; ++j1)
      for (int i2 = 0; i2 <= p; ++i2)
        for (int j2 = 0; j2 < q; ++j2)
          out[(i1 + i2) * (nv + 1) + j1 + j2] +=
              su[static_cast<std::size_t>(i1 * (q + 1) + j1)].cross(
                  sv[static_cast<std::size_t>(i2 * q + j2)]);
  for (int k = 0; k <= nu; ++k)
    for (int l = 0; l <= nv; ++l)
      out[k * (nv + 1) + l] /= c[nu][k] * c[nv][l];
  return (nu + 1) * (nv + 1);
}

FootPiece make_foot_piece(const BezierPatch& bp, const Rect& r, int level_s, int level_t,
                          const DomainEdges& edges) {
  FootPiece f;
  f.rect = r;
  f.level_s = level_s;
  f.level_t = level_t;
  const Grid g = restrict_to(bp, r);
  lengths(g, f.len_s, f.len_t);
  BezierPatch sub;  // the piece in its own parameters [0, 1]^2 (directions only)
  sub.degree_u = g.p;
  sub.degree_v = g.q;
  sub.cw.assign(g.cw.begin(), g.cw.begin() + (g.p + 1) * (g.q + 1));
  sub.param_u = {0.0, 1.0};
  sub.param_v = {0.0, 1.0};
  Vec3 d[6];
  sub.derivatives(0.5, 0.5, d);
  const Vec3 n_raw = d[1].cross(d[2]);
  if (!(n_raw.norm() > 0.0) || !n_raw.allFinite()) {
    f.box = grid_box(g, f.frame);  // eps_n 2: any unit vector is within 2 of any other
    return f;
  }
  const Vec3 n0 = n_raw.normalized();
  Vec3 t1 = d[1] - d[1].dot(n0) * n0;
  t1 = t1.norm() > 0.0 ? t1.normalized() : n0.unitOrthogonal();
  f.frame.e[0] = t1;
  f.frame.e[1] = n0.cross(t1);
  f.frame.e[2] = n0;
  f.box = grid_box(g, f.frame);
  std::array<Vec3, (2 * kMaxDegree) * (2 * kMaxDegree)> normals;
  const int count = normal_control_points(g, normals.data());
  f.eps_n = direction_spread(normals.data(), count, n0);
  f.min_normal = std::numeric_limits<double>::infinity();
  for (int k = 0; k < count; ++k)
    f.min_normal = std::min(f.min_normal, normals[static_cast<std::size_t>(k)].dot(n0));
  for (int i = 0; i <= g.p; ++i) {
    for (int j = 0; j <= g.q; ++j) {
      if (i < g.p) f.max_ss = std::max(f.max_ss, g.p * (g.point(i + 1, j) - g.point(i, j)).norm());
      if (j < g.q) f.max_st = std::max(f.max_st, g.q * (g.point(i, j + 1) - g.point(i, j)).norm());
    }
  }
  // Edge feet: m = +-(tau x n), tau the edge's unit tangent; |m - m0| <= |tau - tau0| +
  // |n - n0| + (1 - |tau0 x n0|) for m0 = +-(tau0 x n0) / |tau0 x n0|.
  for (int k = 0; k < 4; ++k) {
    if (!edges.at[k]) continue;
    const bool u_edge = k < 2;
    const double sign = (k == 0 || k == 2) ? -1.0 : 1.0;
    std::array<Vec3, kMaxDegree> tangent;
    int m = 0;
    if (u_edge) {
      const int i = k == 0 ? 0 : g.p;
      for (int j = 0; j < g.q; ++j)
        tangent[static_cast<std::size_t>(m++)] = g.point(i, j + 1) - g.point(i, j);
    } else {
      const int j = k == 2 ? 0 : g.q;
      for (int i = 0; i < g.p; ++i)
        tangent[static_cast<std::size_t>(m++)] = g.point(i + 1, j) - g.point(i, j);
    }
    Vec3 e[6];
    sub.derivatives(u_edge ? (k == 0 ? 0.0 : 1.0) : 0.5, u_edge ? 0.5 : (k == 2 ? 0.0 : 1.0), e);
    const Vec3 tau0 = (u_edge ? e[2] : e[1]).normalized();
    // m_u = +-(S_t x N) ~ tau x n; m_v = +-(N x S_s) ~ n x tau.
    const Vec3 raw = u_edge ? tau0.cross(n0) : n0.cross(tau0);
    if (!tau0.allFinite() || !(raw.norm() > 0.0)) continue;
    Cone& c = f.cone[f.cones++];
    c.edge = k;
    c.nrm = f.frame.to(n0);
    c.m1 = f.frame.to(sign * raw.normalized());
    c.eps = std::min(
        2.0, f.eps_n + direction_spread(tangent.data(), m, tau0) + f.eps_n + (1.0 - raw.norm()));
  }
  // Corner feet: one point each, its cone evaluated there (eps: rounding only).
  for (int a = 0; a < 2; ++a) {
    for (int b = 2; b < 4; ++b) {
      if (!edges.at[a] || !edges.at[b]) continue;
      Vec3 e[6];
      sub.derivatives(a == 0 ? 0.0 : 1.0, b == 2 ? 0.0 : 1.0, e);
      const Vec3 nc = e[1].cross(e[2]);
      if (!(nc.norm() > 0.0) || !nc.allFinite()) continue;
      const double su_sign = a == 0 ? -1.0 : 1.0, sv_sign = b == 2 ? -1.0 : 1.0;
      Cone& c = f.cone[f.cones++];
      c.corner = true;
      c.nrm = f.frame.to(nc.normalized());
      c.m1 = f.frame.to(su_sign * e[2].cross(nc).normalized());
      c.m2 = f.frame.to(sv_sign * nc.cross(e[1]).normalized());
      c.g1 = f.frame.to(su_sign * e[1]);
      c.g2 = f.frame.to(sv_sign * e[2]);
      c.eps = 1e-12;
    }
  }
  return f;
}

// Kinds of directions: +n, -n, and the boundary cone's sectors th in [k, k + 1] pi / kSectors
// (kBoundary + k).
enum Side { kPlus = 0, kMinus = 1, kBoundary = 2 };
constexpr int kSectors = PreparedModel::kReachSectors;

// The sectors' ends, (cos th, sin th) at th = k pi / kSectors.
struct SectorEnds {
  double c[kSectors + 1], s[kSectors + 1];
  SectorEnds() {
    for (int k = 0; k <= kSectors; ++k) {
      c[k] = std::cos(std::numbers::pi * k / kSectors);
      s[k] = std::sin(std::numbers::pi * k / kSectors);
    }
  }
};
const SectorEnds kSectorEnds;

// max of cos(th) a + sin(th) b over th in the sector's interval: |(a, b)| where the direction of
// (a, b) lies in the sector (counter-clockwise of its low end, clockwise of its high end: the
// sector is narrower than pi), else the larger end value.
double sector_max(int sector, double a, double b) {
  const double c0 = kSectorEnds.c[sector], s0 = kSectorEnds.s[sector];
  const double c1 = kSectorEnds.c[sector + 1], s1 = kSectorEnds.s[sector + 1];
  if (c0 * b - s0 * a >= 0.0 && a * s1 - b * c1 >= 0.0) return std::sqrt(a * a + b * b);
  return std::max(c0 * a + s0 * b, c1 * a + s1 * b);
}

// The largest v.w over the piece's directions of `side` (nominal), plus eps |w|.
double support(const FootPiece& f, int side, const Vec3& w) {
  if (side == kPlus) return w.z() + f.eps_n * w.norm();
  if (side == kMinus) return -w.z() + f.eps_n * w.norm();
  const int sector = side - kBoundary;
  double best = -kInf;
  for (int k = 0; k < f.cones; ++k) {
    const Cone& c = f.cone[k];
    const double a = c.nrm.dot(w);
    double b;
    if (!c.corner) {
      b = c.m1.dot(w);
    } else {
      const Vec3 wt = w - a * c.nrm;
      b = wt.dot(c.g1) >= 0.0 && wt.dot(c.g2) >= 0.0 ? wt.norm()
                                                     : std::max(c.m1.dot(w), c.m2.dot(w));
    }
    // sin(th) >= 0: the best t gives sin(th) b.
    best = std::max(best, sector_max(sector, a, b) + c.eps * w.norm());
  }
  return best;
}

// Lower bound of |w|^2 / (2 v.w) over w = x - f, x in the box `x` (the piece's frame), f in the
// piece, v of `side` with v.w > 0; infinity when no such v.w is positive.
double pair_bound(const FootPiece& f, const Aabb& x, int side) {
  if (side >= kBoundary && f.cones == 0) return kInf;
  const Vec3 lo = x.lo - f.box.hi, hi = x.hi - f.box.lo;
  const double d2 = lo.cwiseMax(0.0).cwiseMax(-hi).squaredNorm();
  if (!(d2 > 0.0)) return 0.0;
  double den = -kInf;
  for (int c = 0; c < 8; ++c) {
    const Vec3 w((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
    den = std::max(den, support(f, side, w));
  }
  if (!(den > 0.0)) return kInf;
  return d2 / (2.0 * den);
}

Aabb node_box_in(const Aabb& box, const Frame& frame) {
  Aabb out;
  for (int c = 0; c < 8; ++c)
    out.extend(frame.to(Vec3((c & 1) ? box.hi.x() : box.lo.x(), (c & 2) ? box.hi.y() : box.lo.y(),
                             (c & 4) ? box.hi.z() : box.lo.z())));
  return out;
}

// The local part over N (global parameters of the surface), for interior feet (v = +-n(f), f
// in the cell, |n(f) - n0| <= eps_n) and for boundary feet (any unit v):
// (sigma - E)^2 / K with K bounding v.S''[Delta, Delta] / |Delta|^2 from above. For v = +n and
// v = -n apart (the side towards which N curves away has K <= 0: no point of N is on the far
// side of the tangent plane, infinity). 0 when N holds a rational patch or the Jacobian bounds
// fail; infinity for an affine N.
struct LocalBound {
  double plus = 0.0, minus = 0.0;
  double boundary[kSectors] = {};
};

LocalBound local_bound(const PreparedModel& model, int surface, const Rect& n, const Vec3& ju0,
                       const Vec3& jv0, const FootPiece& cell, double cell_wu, double cell_wv) {
  LocalBound out;
  const Frame& frame = cell.frame;
  const double eps_n = cell.eps_n;
  // Per edge cone of the cell: its outward conormal m0 (world) and |m0 . S''| components.
  Vec3 m_edge[8];
  double m_uu[8] = {}, m_uv[8] = {}, m_vv[8] = {};
  for (int k = 0; k < cell.cones; ++k) {
    const Vec3& m = cell.cone[k].m1;
    m_edge[k] = m.x() * frame.e[0] + m.y() * frame.e[1] + m.z() * frame.e[2];
  }
  // sigma, two ways: the smallest singular value of J0 less |J - J0| over N; and, with the
  // columns' tangential parts (a, b) in the convex hulls of the hodographs' (the mean Jacobian
  // along a segment is in them), min det(a, b) / sqrt(max |a|^2 + max |b|^2).
  const double a = ju0.squaredNorm(), b = ju0.dot(jv0), c = jv0.squaredNorm();
  const double root = std::sqrt(0.25 * (a - c) * (a - c) + b * b);
  const double lambda_max = 0.5 * (a + c) + root;
  const double lambda_min = lambda_max > 0.0 ? std::max(0.0, a * c - b * b) / lambda_max : 0.0;
  const double sigma0 = std::sqrt(lambda_min);
  double e_u = 0.0, e_v = 0.0;
  double k_uu = 0.0, k_uv = 0.0, k_vv = 0.0;  // |S''| components
  double n_uu = 0.0, n_uv = 0.0, n_vv = 0.0;  // |n0 . S''| components
  // n0 . S'' signed: the largest and smallest of the uu and vv components.
  double hi_uu = -kInf, lo_uu = kInf, hi_vv = -kInf, lo_vv = kInf;
  std::vector<Vec2> hu, hv;  // tangential parts of the hodographs
  const std::int64_t lo = model.locate_patch(surface, n.s0, n.t0);
  const std::int64_t hi = model.locate_patch(surface, n.s1, n.t1);
  if (lo < 0 || hi < 0) return out;
  const auto span_lo = model.patch_span(static_cast<std::size_t>(lo));
  const auto span_hi = model.patch_span(static_cast<std::size_t>(hi));
  const Vec3 n0 = frame.e[2];
  for (int ia = span_lo.a; ia <= span_hi.a; ++ia) {
    for (int ib = span_lo.b; ib <= span_hi.b; ++ib) {
      const std::int64_t k = model.patch_at(surface, ia, ib);
      if (k < 0) continue;
      const PreparedPatch& pp = model.patch(static_cast<std::size_t>(k));
      if (pp.rational) return out;
      const BezierPatch& bp = pp.patch;
      const double pu0 = std::max(n.s0, bp.param_u.lo), pu1 = std::min(n.s1, bp.param_u.hi);
      const double pv0 = std::max(n.t0, bp.param_v.lo), pv1 = std::min(n.t1, bp.param_v.hi);
      if (!(pu1 > pu0 && pv1 > pv0)) continue;
      const Rect r{bp.param_u.to_local(pu0), bp.param_u.to_local(pu1), bp.param_v.to_local(pv0),
                   bp.param_v.to_local(pv1)};
      const Grid g = restrict_to(bp, r);
      const double wu = pu1 - pu0, wv = pv1 - pv0;  // global widths of the part
      const int p = g.p, q = g.q;
      const auto track = [](double& k_all, double& k_n, const Vec3& x, const Vec3& nrm) {
        k_all = std::max(k_all, x.norm());
        k_n = std::max(k_n, std::abs(x.dot(nrm)));
      };
      const auto track_m = [&](double* m_part, const Vec3& x) {
        for (int e = 0; e < cell.cones; ++e)
          m_part[e] = std::max(m_part[e], std::abs(x.dot(m_edge[e])));
      };
      for (int i = 0; i <= p; ++i) {
        for (int j = 0; j <= q; ++j) {
          const Vec3 pij = g.point(i, j);
          if (i < p) {
            const Vec3 su = p * (g.point(i + 1, j) - pij) / wu;
            e_u = std::max(e_u, (su - ju0).norm());
            hu.emplace_back(frame.e[0].dot(su), frame.e[1].dot(su));
          }
          if (j < q) {
            const Vec3 sv = q * (g.point(i, j + 1) - pij) / wv;
            e_v = std::max(e_v, (sv - jv0).norm());
            hv.emplace_back(frame.e[0].dot(sv), frame.e[1].dot(sv));
          }
          if (i + 1 < p) {
            const Vec3 suu =
                p * (p - 1) * (g.point(i + 2, j) - 2.0 * g.point(i + 1, j) + pij) / (wu * wu);
            track(k_uu, n_uu, suu, n0);
            hi_uu = std::max(hi_uu, suu.dot(n0));
            lo_uu = std::min(lo_uu, suu.dot(n0));
            track_m(m_uu, suu);
          }
          if (j + 1 < q) {
            const Vec3 svv =
                q * (q - 1) * (g.point(i, j + 2) - 2.0 * g.point(i, j + 1) + pij) / (wv * wv);
            track(k_vv, n_vv, svv, n0);
            hi_vv = std::max(hi_vv, svv.dot(n0));
            lo_vv = std::min(lo_vv, svv.dot(n0));
            track_m(m_vv, svv);
          }
          if (i < p && j < q) {
            const Vec3 suv = p * q *
                             (g.point(i + 1, j + 1) - g.point(i + 1, j) - g.point(i, j + 1) + pij) /
                             (wu * wv);
            track(k_uv, n_uv, suv, n0);
            track_m(m_uv, suv);
          }
        }
      }
    }
  }
  const double sigma_a = sigma0 - std::sqrt(e_u * e_u + e_v * e_v);
  double det_min = std::numeric_limits<double>::infinity(), max_a = 0.0, max_b = 0.0;
  for (const Vec2& x : hu)
    max_a = std::max(max_a, x.squaredNorm());
  for (const Vec2& y : hv)
    max_b = std::max(max_b, y.squaredNorm());
  for (const Vec2& x : hu)
    for (const Vec2& y : hv)
      det_min = std::min(det_min, x.x() * y.y() - x.y() * y.x());
  const double sigma_b = det_min > 0.0 ? det_min / std::sqrt(max_a + max_b) : 0.0;
  const double sigma = std::max(sigma_a, sigma_b);
  if (!(sigma > 0.0)) return out;
  // |Delta^T S'' Delta| <= [|du| |dv|] [[k_uu, k_uv], [k_uv, k_vv]] [|du| |dv|]^T.
  const auto lambda = [](double uu, double uv, double vv) {
    return 0.5 * (uu + vv) + std::sqrt(0.25 * (uu - vv) * (uu - vv) + uv * uv);
  };
  const double k_all = lambda(k_uu, k_uv, k_vv);
  const double k_int = std::min(k_all, lambda(n_uu, n_uv, n_vv) + eps_n * k_all);
  // Per side: +-n0 . S''[Delta, Delta] <= [|du| |dv|] [[h_uu, n_uv], [n_uv, h_vv]] [|du| |dv|]^T
  // with h the signed extremes (h_uu = max n0 . S_uu for +n, -min for -n): at most lambda_max of
  // that matrix (negative when N curves away on that side) times |Delta|^2. No uu or vv term
  // (degree 1 in that direction): 0.
  const auto signed_lambda = [&](double uu, double vv) {
    uu = uu > -kInf ? uu : 0.0;
    vv = vv > -kInf ? vv : 0.0;
    return std::min(k_int, lambda(uu, n_uv, vv) + eps_n * k_all);
  };
  const double k_plus = signed_lambda(hi_uu, hi_vv);
  const double k_minus = signed_lambda(-lo_uu, -lo_vv);
  out.plus = k_plus > 0.0 ? sigma * sigma / k_plus : kInf;
  out.minus = k_minus > 0.0 ? sigma * sigma / k_minus : kInf;
  // Boundary feet: v = cos th n + sin th t with t in the outward tangential cone. For a u edge
  // (m outward, m . S_v = 0), with Delta pointing into the domain,
  //   m . (x - f) <= -c |du| + (m_uu du^2 + 2 m_uv |du| |dv| + m_vv dv^2) / 2,
  // c = m . S_u >= min |N| / max |S_v| on the cell's edge. Where c dominates the mixed terms over
  // N (c >= m_uu R_u / 2 + m_uv R_v), m . (x - f) <= m_vv dv^2 / 2: only the edge curve's own
  // bending in the tangent plane. Then v . (x - f) <= (k_n + m_vv) |Delta|^2 / 2. Otherwise (and
  // as a bound in any case) |S''| itself.
  double k_boundary = k_all;
  if (cell.cones > 0 && cell.min_normal > 0.0) {
    const double r_u = n.s1 - n.s0, r_v = n.t1 - n.t0;
    // Global units: N / (cell_wu cell_wv), S_s / cell_wu, S_t / cell_wv.
    const double c_u = cell.min_normal / (cell.max_st * cell_wu);  // m_u . S_u on a u edge
    const double c_v = cell.min_normal / (cell.max_ss * cell_wv);  // m_v . S_v on a v edge
    double edge_term[4] = {kInf, kInf, kInf, kInf};
    double worst = 0.0;
    bool ok = true;
    for (int k = 0; k < cell.cones && ok; ++k) {
      const Cone& c = cell.cone[k];
      if (c.corner) continue;
      const double e = c.eps;  // >= |m - m0|
      const double uu = m_uu[k] + e * k_uu, uv = m_uv[k] + e * k_uv, vv = m_vv[k] + e * k_vv;
      double term;
      if (c.edge < 2) {
        ok = c_u >= 0.5 * uu * r_u + uv * r_v;
        term = vv;
      } else {
        ok = c_v >= 0.5 * vv * r_v + uv * r_u;
        term = uu;
      }
      edge_term[c.edge] = term;
      worst = std::max(worst, term);
    }
    for (int k = 0; k < cell.cones && ok; ++k) {
      const Cone& c = cell.cone[k];
      if (!c.corner) continue;
      // t = (a m_u + b m_v) / |.|, a, b >= 0: |a m_u + b m_v| >= (a + b) cos(phi / 2).
      const double half_cos = std::sqrt(std::max(0.0, 0.5 * (1.0 + c.m1.dot(c.m2))));
      double both = 0.0;
      for (int e = 0; e < 4; ++e)
        if (edge_term[e] < kInf) both = std::max(both, edge_term[e]);
      ok = half_cos > 0.0;
      if (ok) worst = std::max(worst, both / half_cos);
    }
    if (ok) k_boundary = std::min(k_all, k_int + worst);
    // Per sector: v . (x - f) <= cos th n . (x - f) + sin th t . (x - f).
    for (int k = 0; k < kSectors && ok; ++k) {
      const double lo = std::numbers::pi * k / kSectors, hi = std::numbers::pi * (k + 1) / kSectors;
      const double sin_max = lo <= 0.5 * std::numbers::pi && hi >= 0.5 * std::numbers::pi
                                 ? 1.0
                                 : std::max(std::sin(lo), std::sin(hi));
      // The normal part cos th n . (x - f): +n's bound for th below pi / 2, -n's above (|cos th|
      // times it), largest at an end of the sector (or 0 at pi / 2).
      const auto normal_part = [&](double th) {
        const double c = std::cos(th);
        return c >= 0.0 ? c * k_plus : -c * k_minus;
      };
      double cos_part = std::max(normal_part(lo), normal_part(hi));
      if (lo < 0.5 * std::numbers::pi && hi > 0.5 * std::numbers::pi)
        cos_part = std::max(cos_part, 0.0);
      const double k_sector = std::min(k_all, cos_part + sin_max * worst);
      out.boundary[k] = k_sector > 0.0 ? sigma * sigma / k_sector : kInf;
    }
    if (ok) return out;
  }
  for (int k = 0; k < kSectors; ++k)
    out.boundary[k] = k_boundary > 0.0 ? sigma * sigma / k_boundary : kInf;
  return out;
}

// A piece is halved across its longer side (3-D length), until kMaxLevel halvings of that side.
bool split_along_s(int level_s, int level_t, double len_s, double len_t) {
  return level_t >= kMaxLevel || (level_s < kMaxLevel && len_s >= len_t);
}

// The low (half 0) or high half of r along s or t.
Rect half_of(Rect r, bool along_s, int half) {
  double& lo = along_s ? r.s0 : r.t0;
  double& hi = along_s ? r.s1 : r.t1;
  const double mid = 0.5 * (lo + hi);
  (half == 0 ? hi : lo) = mid;
  return r;
}

// Per-thread working memory of the search.
struct Search {
  std::vector<FootPiece> feet;
  std::vector<ModelPiece> pieces;
  std::vector<Vec4> pool;
  struct Entry {
    double bound;
    std::int32_t foot;
    std::int64_t x;       // >= 0: pieces[x]; < 0: hierarchy node ~x
    double x_diag = 0.0;  // a piece's box diagonal in the foot piece's frame
    bool operator>(const Entry& o) const { return bound > o.bound; }
  };
  std::vector<Entry> heap;
};

class CellBounds {
 public:
  CellBounds(const PreparedModel& model, Search& search) : model_(model), s_(search) {}

  // The far part's bound for `side`, refined up to `target`.
  double far_bound(const FootPiece& cell, std::uint32_t cell_patch, int surface,
                   const Rect& n_global, int side, double target) {
    s_.feet.clear();
    s_.pieces.clear();
    s_.heap.clear();
    s_.pool.clear();
    s_.feet.push_back(cell);
    cell_patch_ = cell_patch;
    surface_ = surface;
    n_ = n_global;
    side_ = side;
    target_ = target;
    const auto& nodes = model_.patch_hierarchy().nodes();
    if (nodes.empty()) return target;
    push_node(0, 0);
    int pops = 0;
    while (!s_.heap.empty()) {
      std::pop_heap(s_.heap.begin(), s_.heap.end(), std::greater<>());
      const Search::Entry e = s_.heap.back();
      s_.heap.pop_back();
      if (e.bound >= target_) return target_;
      if (++pops > (side_ >= kBoundary ? kBoundaryBudget : kBudget)) return e.bound;
      if (e.x < 0) {
        expand_node(e.foot, static_cast<std::uint32_t>(~e.x));
        continue;
      }
      // Split the larger of the two pieces (by box diagonal in the foot piece's frame).
      const FootPiece& f = s_.feet[static_cast<std::size_t>(e.foot)];
      const ModelPiece& x = s_.pieces[static_cast<std::size_t>(e.x)];
      const bool f_can = f.level_s < kMaxLevel || f.level_t < kMaxLevel;
      const bool x_can = x.level_s < kMaxLevel || x.level_t < kMaxLevel;
      if (!f_can && !x_can) return e.bound;
      const double f_diag = f.box.diagonal();
      if (f_can && (!x_can || f_diag >= e.x_diag)) {
        split_foot(e.foot, e.x);
      } else {
        split_piece(e.foot, e.x);
      }
    }
    return target_;
  }

 private:
  void push(std::int32_t foot, std::int64_t x, double bound, double x_diag = 0.0) {
    if (!(bound < target_)) return;  // never needed: the search stops before reaching it
    s_.heap.push_back({bound, foot, x, x_diag});
    std::push_heap(s_.heap.begin(), s_.heap.end(), std::greater<>());
  }

  void push_node(std::int32_t foot, std::uint32_t node) {
    const FootPiece& f = s_.feet[static_cast<std::size_t>(foot)];
    const Aabb& box = model_.patch_hierarchy().nodes()[node].box;
    push(foot, ~static_cast<std::int64_t>(node), pair_bound(f, node_box_in(box, f.frame), side_));
  }

  void push_piece(std::int32_t foot, std::int64_t x) {
    const FootPiece& f = s_.feet[static_cast<std::size_t>(foot)];
    const ModelPiece& m = s_.pieces[static_cast<std::size_t>(x)];
    const Aabb box = piece_box(m, f.frame);
    push(foot, x, pair_bound(f, box, side_), box.diagonal());
  }

  Aabb piece_box(const ModelPiece& m, const Frame& frame) const {
    return points_box(s_.pool.data() + m.offset, (m.p + 1) * (m.q + 1), frame);
  }

  Grid piece_grid(const ModelPiece& m) const {
    Grid g;
    g.p = m.p;
    g.q = m.q;
    std::copy_n(s_.pool.begin() + static_cast<std::ptrdiff_t>(m.offset), (m.p + 1) * (m.q + 1),
                g.cw.begin());
    return g;
  }

  std::int64_t add_piece(const Rect& r, int level_s, int level_t, const Grid& grid) {
    ModelPiece m;
    m.rect = r;
    m.level_s = level_s;
    m.level_t = level_t;
    m.p = grid.p;
    m.q = grid.q;
    m.offset = s_.pool.size();
    s_.pool.insert(s_.pool.end(), grid.cw.begin(), grid.cw.begin() + (grid.p + 1) * (grid.q + 1));
    lengths(grid, m.len_s, m.len_t);
    s_.pieces.push_back(m);
    return static_cast<std::int64_t>(s_.pieces.size() - 1);
  }

  void expand_node(std::int32_t foot, std::uint32_t node_index) {
    const Bvh& bvh = model_.patch_hierarchy();
    const Bvh::Node& node = bvh.nodes()[node_index];
    if (node.count == 0) {
      push_node(foot, node.first);
      push_node(foot, node.first + 1);
      return;
    }
    for (std::uint32_t k = node.first; k < node.first + node.count; ++k) {
      const std::uint32_t item = bvh.order()[k];
      // Trim-edge pieces lie on their faces' patches, which are items too.
      if (item >= model_.hierarchy_patch_items()) continue;
      const std::uint32_t patch = model_.item_patch(item);
      const BezierPatch& bp = model_.patch(patch).patch;
      Rect inside{0.0, 0.0, 0.0, 0.0};
      bool overlaps = false;
      if (model_.patch_surface(patch) == surface_) {
        const double u0 = std::max(n_.s0, bp.param_u.lo), u1 = std::min(n_.s1, bp.param_u.hi);
        const double v0 = std::max(n_.t0, bp.param_v.lo), v1 = std::min(n_.t1, bp.param_v.hi);
        if (u1 > u0 && v1 > v0) {
          overlaps = true;
          inside = {bp.param_u.to_local(u0), bp.param_u.to_local(u1), bp.param_v.to_local(v0),
                    bp.param_v.to_local(v1)};
        }
      }
      if (!overlaps) {
        push_piece(foot, add_piece(Rect{}, 0, 0, restrict_to(bp, Rect{})));
        continue;
      }
      // The patch outside N: up to four rectangles around N's part.
      Rect parts[4];
      int count = 0;
      if (inside.s0 > 0.0) parts[count++] = {0.0, inside.s0, 0.0, 1.0};
      if (inside.s1 < 1.0) parts[count++] = {inside.s1, 1.0, 0.0, 1.0};
      if (inside.t0 > 0.0) parts[count++] = {inside.s0, inside.s1, 0.0, inside.t0};
      if (inside.t1 < 1.0) parts[count++] = {inside.s0, inside.s1, inside.t1, 1.0};
      for (int c = 0; c < count; ++c)
        push_piece(foot, add_piece(parts[c], 0, 0, restrict_to(bp, parts[c])));
    }
  }

  void split_foot(std::int32_t foot, std::int64_t x) {
    if (s_.feet[static_cast<std::size_t>(foot)].child[0] < 0) {
      const FootPiece f = s_.feet[static_cast<std::size_t>(foot)];
      const bool along_s = split_along_s(f.level_s, f.level_t, f.len_s, f.len_t);
      const BezierPatch& bp = model_.patch(cell_patch_).patch;
      const NurbsSurface& surface = model_.model().surfaces[static_cast<std::size_t>(surface_)];
      std::int32_t children[2];
      for (int half = 0; half < 2; ++half) {
        const Rect r = half_of(f.rect, along_s, half);
        s_.feet.push_back(make_foot_piece(bp, r, f.level_s + (along_s ? 1 : 0),
                                          f.level_t + (along_s ? 0 : 1),
                                          touched_edges(bp, r, surface)));
        children[half] = static_cast<std::int32_t>(s_.feet.size() - 1);
      }
      s_.feet[static_cast<std::size_t>(foot)].child[0] = children[0];
      s_.feet[static_cast<std::size_t>(foot)].child[1] = children[1];
    }
    for (int half = 0; half < 2; ++half) {
      const std::int32_t child = s_.feet[static_cast<std::size_t>(foot)].child[half];
      if (x < 0)
        push_node(child, static_cast<std::uint32_t>(~x));
      else
        push_piece(child, x);
    }
  }

  void split_piece(std::int32_t foot, std::int64_t x) {
    if (s_.pieces[static_cast<std::size_t>(x)].child[0] < 0) {
      const ModelPiece m = s_.pieces[static_cast<std::size_t>(x)];
      const Grid whole = piece_grid(m);
      const bool along_s = split_along_s(m.level_s, m.level_t, m.len_s, m.len_t);
      Grid halves[2];
      split(whole, along_s ? 0 : 1, 0.5, halves[0], halves[1]);
      std::int64_t children[2];
      for (int half = 0; half < 2; ++half) {
        const Rect r = half_of(m.rect, along_s, half);
        const Grid& g = halves[half];
        children[half] =
            add_piece(r, m.level_s + (along_s ? 1 : 0), m.level_t + (along_s ? 0 : 1), g);
      }
      s_.pieces[static_cast<std::size_t>(x)].child[0] = children[0];
      s_.pieces[static_cast<std::size_t>(x)].child[1] = children[1];
    }
    for (int half = 0; half < 2; ++half)
      push_piece(foot, s_.pieces[static_cast<std::size_t>(x)].child[half]);
  }

 private:
  const PreparedModel& model_;
  Search& s_;
  std::uint32_t cell_patch_ = 0;  // the patch of the cell (its feet's pieces)
  int surface_ = -1;
  Rect n_;  // N in the surface's global parameters (s = u, t = v)
  int side_ = kPlus;
  double target_ = 0.0;
};

// Rounded down to a float, with room for the double arithmetic's rounding.
float round_down(double x) {
  if (!(x > 0.0)) return 0.0f;
  x *= 1.0 - 1e-9;
  if (x >= double(std::numeric_limits<float>::max())) return std::numeric_limits<float>::max();
  float f = static_cast<float>(x);
  if (double(f) > x) f = std::nextafter(f, 0.0f);
  return f;
}

}  // namespace

ReachTable build_reach_table(const PreparedModel& model) {
  ReachTable table;
  table.first.assign(model.patch_count(), PreparedModel::kNoReach);
  std::vector<std::uint32_t> with_cells;
  for (std::size_t i = 0; i < model.patch_count(); ++i) {
    const int s = model.patch_surface(i);
    // Untrimmed polynomial surfaces only: a Newton foot on a trimmed face may lie outside it.
    if (model.surface_region(s) != nullptr || !model.surface_certifiable(s) ||
        model.patch(i).rational) {
      continue;
    }
    with_cells.push_back(static_cast<std::uint32_t>(i));
  }
  // Smaller cells give tighter bounds (the normal varies less over them); at most kCellBudget
  // cells in all keeps construction near 0.2 s per thousand cells on 2 cores (the peers
  // benchmark's 49-patch panel: 16 x 16 cells a patch prove 89% of its points in 2.3 s, 8 x 8
  // cells 84% in 0.9 s). Powers of two: the lookup's s * k is exact.
  const std::size_t patches = with_cells.size();
  const int K = patches * 256 <= kCellBudget  ? 16
                : patches * 64 <= kCellBudget ? 8
                : patches * 16 <= kCellBudget ? 4
                : patches * 4 <= kCellBudget  ? 2
                                              : 1;
  table.cells_per_side = K;
  for (std::size_t w = 0; w < patches; ++w)
    table.first[with_cells[w]] = static_cast<std::uint32_t>(w * K * K);
  table.cells.resize(with_cells.size() * K * K);
  // Bounds beyond half the model's size prove little more in practice (a point that far from
  // the model is rare); the cap ends the search early.
  const double cap = 0.5 * std::max(model.bounds().diagonal(), 1e-300);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, with_cells.size(), 4), [&](const auto&
                                                                                      range) {
    Search search;
    CellBounds bounds(model, search);
    for (std::size_t w = range.begin(); w != range.end(); ++w) {
      const std::uint32_t patch = with_cells[w];
      const int surface = model.patch_surface(patch);
      const NurbsSurface& s = model.model().surfaces[static_cast<std::size_t>(surface)];
      const BezierPatch& bp = model.patch(patch).patch;
      const bool c1 = model.surface_c1(surface);
      for (int ci = 0; ci < K; ++ci) {
        for (int cj = 0; cj < K; ++cj) {
          const Rect cell{double(ci) / K, double(ci + 1) / K, double(cj) / K, double(cj + 1) / K};
          // N: the cell grown by its own width (global parameters), within the domain, and
          // within the patch unless the surface is C1 across patch edges.
          const double wu = bp.param_u.hi - bp.param_u.lo, wv = bp.param_v.hi - bp.param_v.lo;
          const double lo_u = c1 ? s.domain_u().lo : bp.param_u.lo;
          const double hi_u = c1 ? s.domain_u().hi : bp.param_u.hi;
          const double lo_v = c1 ? s.domain_v().lo : bp.param_v.lo;
          const double hi_v = c1 ? s.domain_v().hi : bp.param_v.hi;
          const double margin = margin_in_cells(K) / K;
          // An edge of N that rounding put next to the patch's own edge goes onto it: a sliver of
          // a neighbour (width ~1e-16) would divide its hodographs' rounding by its width.
          const auto snap = [](double x, const ParamInterval& patch_range) {
            const double tol = 1e-9 * (patch_range.hi - patch_range.lo);
            if (std::abs(x - patch_range.lo) <= tol) return patch_range.lo;
            if (std::abs(x - patch_range.hi) <= tol) return patch_range.hi;
            return x;
          };
          const Rect n{
              std::max(lo_u, snap(bp.param_u.to_parent(cell.s0) - margin * wu, bp.param_u)),
              std::min(hi_u, snap(bp.param_u.to_parent(cell.s1) + margin * wu, bp.param_u)),
              std::max(lo_v, snap(bp.param_v.to_parent(cell.t0) - margin * wv, bp.param_v)),
              std::min(hi_v, snap(bp.param_v.to_parent(cell.t1) + margin * wv, bp.param_v))};
          Vec3 d[6];
          bp.derivatives(0.5 * (cell.s0 + cell.s1), 0.5 * (cell.t0 + cell.t1), d);
          const DomainEdges edges = touched_edges(bp, cell, s);
          const FootPiece foot = make_foot_piece(bp, cell, 0, 0, edges);
          const LocalBound local =
              local_bound(model, surface, n, d[1] / wu, d[2] / wv, foot, wu / K, wv / K);
          PreparedModel::ReachCell& out =
              table.cells[table.first[patch] + static_cast<std::uint32_t>(ci * K + cj)];
          const double target_plus = std::min(local.plus, cap);
          if (target_plus > 0.0) {
            out.plus = round_down(bounds.far_bound(foot, patch, surface, n, kPlus, target_plus));
          }
          const double target_minus = std::min(local.minus, cap);
          if (target_minus > 0.0) {
            out.minus = round_down(bounds.far_bound(foot, patch, surface, n, kMinus, target_minus));
          }
          for (int k = 0; k < kSectors && foot.cones > 0; ++k) {
            const double target_b = std::min(local.boundary[k], cap);
            if (target_b > 0.0) {
              out.boundary[k] =
                  round_down(bounds.far_bound(foot, patch, surface, n, kBoundary + k, target_b));
            }
          }
        }
      }
    }
  });
  nurbsreg::engine::stop_if_cancelled();
  return table;
}

}  // namespace nurbsreg::engine
