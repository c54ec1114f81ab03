// TrimRegion: the trim loops cut into rational Bézier pieces monotone in u and in v, plus a grid
// over the region's bounding box that answers most queries at once.
//
// Exactness: a horizontal ray from (u, v) to +u crosses a v-monotone piece at most once, and
// counting a piece only when v lies in the half-open range [min, max) of its end v's makes the
// count right at shared vertices and for horizontal pieces (the classic polygon rule, applied to
// curved pieces). Consecutive pieces share their end points bit for bit (gaps, even of one ulp,
// are closed by straight pieces), so every loop is a closed chain and the parity is exact up to
// the rounding of the crossing's position (and the 1e-14 x scale tolerance of the monotonicity
// test).
//
// Grid: cells met by a loop (found by subdividing its pieces down to cell size, with a margin
// for the rounding of the cell mapping) are `boundary`; every other cell holds no loop point,
// so it is uniformly inside or outside, decided once by a sweep along the row's centre line.
// contains() answers from the cell unless it is a boundary cell; classify() sums cells with 2-D
// prefix sums. Cost measured in tests/engine/trim_region_test.cpp (ReportQueryCost).

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "bernstein/binomial_table.hpp"
#include "bernstein/de_casteljau.hpp"
#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/trim_region.hpp"

namespace nurbsreg::engine {
namespace {

using Piece = TrimRegion::Piece;

constexpr BinomialTable<kMaxDegree> kBinomials;
constexpr int kMaxSplitDepth = 48;    // monotone splitting during construction
constexpr int kMaxSearchDepth = 64;   // crossing_u (construction)
constexpr int kMaxSearchSteps = 200;  // crossing search per query
constexpr int kMaxMarkDepth = 30;     // boundary-cell marking
constexpr int kMinCellsPerSide = 16;
// Memory: about 9 bytes per cell (class + two prefix sums), 0.6 MB at the cap.
constexpr int kMaxCellsPerSide = 256;

double euclid_u(const Vec3& p) {
  return p.x() / p.z();
}
double euclid_v(const Vec3& p) {
  return p.y() / p.z();
}

Piece make_piece(const Vec3* cw, int degree) {
  Piece p;
  p.degree = degree;
  p.u_lo = std::numeric_limits<double>::infinity();
  p.u_hi = -p.u_lo;
  for (int i = 0; i <= degree; ++i) {
    p.cw[i] = cw[i];
    p.cb[i] = kBinomials.c[degree][i] * cw[i];
    const double u = euclid_u(cw[i]);
    p.u_lo = std::min(p.u_lo, u);
    p.u_hi = std::max(p.u_hi, u);
  }
  p.u_start = euclid_u(cw[0]);
  p.v_start = euclid_v(cw[0]);
  p.u_end = euclid_u(cw[degree]);
  p.v_end = euclid_v(cw[degree]);
  return p;
}

Piece make_segment(double u0, double v0, double u1, double v1) {
  const Vec3 cw[2] = {Vec3(u0, v0, 1.0), Vec3(u1, v1, 1.0)};
  Piece p = make_piece(cw, 1);
  // Exact end points (division by 1 is exact anyway; this documents the intent).
  p.u_start = u0;
  p.v_start = v0;
  p.u_end = u1;
  p.v_end = v1;
  return p;
}

double piece_v_lo(const Piece& p) {
  return std::min(p.v_start, p.v_end);
}
double piece_v_hi(const Piece& p) {
  return std::max(p.v_start, p.v_end);
}
double piece_v_min_cp(const Piece& p) {
  double lo = std::numeric_limits<double>::infinity();
  for (int i = 0; i <= p.degree; ++i)
    lo = std::min(lo, euclid_v(p.cw[i]));
  return lo;
}
double piece_v_max_cp(const Piece& p) {
  double hi = -std::numeric_limits<double>::infinity();
  for (int i = 0; i <= p.degree; ++i)
    hi = std::max(hi, euclid_v(p.cw[i]));
  return hi;
}

// Homogeneous point of the piece at t, up to a positive factor (only ratios are used):
// Bernstein Horner in s = t / (1 - t) or (1 - t) / t, whichever is <= 1. O(degree).
Vec3 scaled_point(const Piece& p, double t) {
  const int n = p.degree;
  Vec3 acc;
  if (t <= 0.5) {
    const double s = t / (1.0 - t);
    acc = p.cb[n];
    for (int i = n - 1; i >= 0; --i)
      acc = acc * s + p.cb[i];
  } else {
    const double r = (1.0 - t) / t;
    acc = p.cb[0];
    for (int i = 1; i <= n; ++i)
      acc = acc * r + p.cb[i];
  }
  return acc;
}

// Is the crossing of the piece with the line v = const (v in the piece's half-open v range)
// right of u? The piece is monotone in u and v, so on a bracket [ta, tb] of the crossing its u
// range is [u(ta), u(tb)]: the bracket is narrowed (Illinois variant of regula falsi on
// v(t) - v) until that range lies on one side of u. No allocation.
bool crossing_right_of(const Piece& p, double u, double v) {
  double ua = p.u_start, ub = p.u_end;
  if (u < std::min(ua, ub)) return true;
  if (u > std::max(ua, ub)) return false;
  if (p.degree == 1) {
    // A rational line is the segment between its end points whatever its weights.
    const double s = (v - p.v_start) / (p.v_end - p.v_start);
    return p.u_start + s * (p.u_end - p.u_start) > u;
  }
  double ta = 0.0, tb = 1.0;
  double fa = p.v_start - v, fb = p.v_end - v;  // opposite signs (or fa == 0)
  if (fa == 0.0) return ua > u;
  if (fb == 0.0) return ub > u;
  int side = 0;
  for (int it = 0; it < kMaxSearchSteps; ++it) {
    double t = (ta * fb - tb * fa) / (fb - fa);
    if (!(t > ta && t < tb)) t = 0.5 * (ta + tb);
    if (!(t > ta && t < tb)) break;  // the bracket is one ulp wide
    const Vec3 q = scaled_point(p, t);
    const double ut = q.x() / q.z(), ft = q.y() / q.z() - v;
    if (ft == 0.0) return ut > u;
    if ((ft > 0.0) == (fb > 0.0)) {
      tb = t;
      ub = ut;
      fb = ft;
      if (side == -1) fa *= 0.5;
      side = -1;
    } else {
      ta = t;
      ua = ut;
      fa = ft;
      if (side == 1) fb *= 0.5;
      side = 1;
    }
    if (u < std::min(ua, ub)) return true;
    if (u > std::max(ua, ub)) return false;
  }
  return 0.5 * (ua + ub) > u;  // (u, v) is on the loop to rounding: either answer
}

// u of the piece's crossing with the line v = const, to within `tolerance` (construction only:
// the row sweep compares it with the centres of cells no loop meets, which lie half a cell or
// more from any loop point, so a fraction of a cell decides every comparison as the exact
// crossing would). The piece is monotone in u, so the control points' u range of the half that
// holds the crossing brackets it.
double crossing_u(const Piece& p, double v, double tolerance) {
  if (p.degree == 1) {
    const double s = (v - p.v_start) / (p.v_end - p.v_start);
    return p.u_start + s * (p.u_end - p.u_start);
  }
  const int n = p.degree;
  const bool increasing = p.v_end > p.v_start;
  Vec3 a[kMaxDegree + 1], left[kMaxDegree + 1], right[kMaxDegree + 1];
  for (int i = 0; i <= n; ++i)
    a[i] = p.cw[i];
  for (int depth = 0; depth < kMaxSearchDepth; ++depth) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int i = 0; i <= n; ++i) {
      lo = std::min(lo, euclid_u(a[i]));
      hi = std::max(hi, euclid_u(a[i]));
    }
    if (hi - lo <= tolerance) return 0.5 * (lo + hi);
    halve(a, 1, n, left, right);
    const Vec3& mid = left[n];
    const bool in_left = increasing ? v * mid.z() < mid.y() : v * mid.z() > mid.y();
    const Vec3* half = in_left ? left : right;
    for (int i = 0; i <= n; ++i)
      a[i] = half[i];
  }
  return euclid_u(a[0]);
}

// Cuts 2-D rational Bézier curves (homogeneous (w u, w v, w)) into pieces monotone in v and
// in u: v monotone makes a horizontal line meet a piece at most once; u monotone makes the u
// range of any part of a piece the range of its end points (the query's cheap bracket test).
class MonotoneSplitter {
 public:
  MonotoneSplitter(double tolerance, double tiny) : tolerance_(tolerance), tiny_(tiny) {}

  void add(const BezierCurve& curve, std::vector<Piece>& out) const {
    BezierCurve c2 = curve;
    for (int i = 0; i <= c2.degree; ++i)
      c2.cw[i] = Vec4(curve.cw[i][0], curve.cw[i][1], 0.0, curve.cw[i][3]);
    split(c2, 0, out);
  }

 private:
  static Vec3 h(const BezierCurve& c, int i) { return Vec3(c.cw[i][0], c.cw[i][1], c.cw[i][3]); }

  // Are the control points' coordinates `axis` (0: u, 1: v) monotone (to rounding)?
  bool monotone(const BezierCurve& c, int axis) const {
    bool up = true, down = true;
    for (int i = 1; i <= c.degree; ++i) {
      const double d = c.cw[i][axis] / c.cw[i][3] - c.cw[i - 1][axis] / c.cw[i - 1][3];
      up = up && d >= -tolerance_;
      down = down && d <= tolerance_;
    }
    return up || down;
  }

  static double slope(const BezierCurve& c, double t, int axis) {
    Vec3 d[2];
    c.derivatives(t, 1, d);
    return d[1][axis];
  }

  // A parameter in (0, 1) where coordinate `axis` has an extremum (sign change of its
  // derivative found by sampling, then bisection), or 0.5 when sampling finds none.
  static double split_parameter(const BezierCurve& c, int axis) {
    const int samples = 4 * c.degree + 4;
    double t_prev = 0.0, s_prev = slope(c, 0.0, axis);
    for (int k = 1; k <= samples; ++k) {
      const double t = static_cast<double>(k) / samples;
      const double s = slope(c, t, axis);
      if (s_prev != 0.0 && s != 0.0 && (s > 0.0) != (s_prev > 0.0)) {
        double lo = t_prev, hi = t;
        for (int it = 0; it < 60 && hi - lo > 1e-15; ++it) {
          const double mid = 0.5 * (lo + hi);
          const double sm = slope(c, mid, axis);
          if (sm == 0.0) {
            lo = hi = mid;
          } else if ((sm > 0.0) == (s_prev > 0.0)) {
            lo = mid;
          } else {
            hi = mid;
          }
        }
        const double root = 0.5 * (lo + hi);
        return root > 1e-6 && root < 1.0 - 1e-6 ? root : 0.5;
      }
      if (s != 0.0) {
        t_prev = t;
        s_prev = s;
      }
    }
    return 0.5;
  }

  void split(const BezierCurve& c, int depth, std::vector<Piece>& out) const {
    Vec3 cw[kMaxDegree + 1];
    for (int i = 0; i <= c.degree; ++i)
      cw[i] = h(c, i);
    const bool v_monotone = monotone(c, 1);
    if (c.degree == 1 || (v_monotone && monotone(c, 0))) {
      out.push_back(make_piece(cw, c.degree));
      return;
    }
    double u_lo = std::numeric_limits<double>::infinity(), u_hi = -u_lo;
    double v_lo = u_lo, v_hi = -u_lo;
    for (int i = 0; i <= c.degree; ++i) {
      u_lo = std::min(u_lo, euclid_u(cw[i]));
      u_hi = std::max(u_hi, euclid_u(cw[i]));
      v_lo = std::min(v_lo, euclid_v(cw[i]));
      v_hi = std::max(v_hi, euclid_v(cw[i]));
    }
    if (depth >= kMaxSplitDepth || std::max(u_hi - u_lo, v_hi - v_lo) < tiny_) {
      // Tiny (or pathological) piece: its chord, which keeps the loop closed.
      const Vec3 chord[2] = {cw[0], cw[c.degree]};
      out.push_back(make_piece(chord, 1));
      return;
    }
    BezierCurve left, right;
    c.split(split_parameter(c, v_monotone ? 0 : 1), left, right);
    split(left, depth + 1, out);
    split(right, depth + 1, out);
  }

  double tolerance_, tiny_;
};

}  // namespace

int TrimRegion::cell_u(double u) const {
  const int i = static_cast<int>((u - du_.lo) * inv_cell_u_);
  return std::clamp(i, 0, cells_u_ - 1);
}
int TrimRegion::cell_v(double v) const {
  const int i = static_cast<int>((v - dv_.lo) * inv_cell_v_);
  return std::clamp(i, 0, cells_v_ - 1);
}

TrimRegion::TrimRegion(const NurbsSurface& surface) {
  if (!surface.is_trimmed())
    throw std::invalid_argument("TrimRegion: the surface has no trim loops");
  // Only what the region needs: the domain and the uv curves (a missing 3-D edge is
  // trim_edges()'s concern, not the region's).
  if (surface.degree_u < 1 || surface.degree_v < 1 || surface.count_u <= surface.degree_u ||
      surface.count_v <= surface.degree_v ||
      surface.knots_u.size() != static_cast<std::size_t>(surface.count_u + surface.degree_u + 1) ||
      surface.knots_v.size() != static_cast<std::size_t>(surface.count_v + surface.degree_v + 1) ||
      !(surface.domain_u().width() > 0.0) || !(surface.domain_v().width() > 0.0)) {
    throw std::invalid_argument("TrimRegion: surface '" + surface.name +
                                "': invalid degrees, knots or domain");
  }
  for (std::size_t l = 0; l < surface.trim_loops.size(); ++l) {
    const std::string loop = "TrimRegion: trim_loops[" + std::to_string(l) + "]";
    if (surface.trim_loops[l].curves.empty()) {
      throw std::invalid_argument(loop + ".curves: a loop needs at least one curve");
    }
    for (std::size_t c = 0; c < surface.trim_loops[l].curves.size(); ++c) {
      const NurbsCurve& uv = surface.trim_loops[l].curves[c].uv;
      const std::string field = loop + ".curves[" + std::to_string(c) + "].uv";
      if (auto e = uv.validate()) throw std::invalid_argument(field + ": " + *e);
      if (uv.dimension != 2) throw std::invalid_argument(field + ": must be a 2-D curve");
    }
  }
  const ParamInterval dom_u = surface.domain_u(), dom_v = surface.domain_v();

  // Scale of the parameter space, for the rounding-level tolerances below.
  double scale = std::max({std::abs(dom_u.lo), std::abs(dom_u.hi), std::abs(dom_v.lo),
                           std::abs(dom_v.hi), dom_u.width(), dom_v.width()});
  for (const TrimLoop& loop : surface.trim_loops) {
    for (const TrimCurve& curve : loop.curves) {
      for (const Vec3& p : curve.uv.control_points)
        scale = std::max({scale, std::abs(p.x()), std::abs(p.y())});
    }
  }
  const MonotoneSplitter splitter(1e-14 * scale, 1e-13 * scale);
  // The region is defined only to the splitter's chord tolerance: loop parts within it of the
  // grid box's edge are taken to lie on that edge (see mark_piece and classify).
  band_ = 1e-13 * scale;

  // 1. Monotone pieces, loop by loop, chained end to start.
  for (const TrimLoop& loop : surface.trim_loops) {
    const std::size_t first = pieces_.size();
    for (const TrimCurve& curve : loop.curves) {
      for (const BezierCurve& bez : decompose(curve.uv)) {
        const std::size_t before = pieces_.size();
        splitter.add(bez, pieces_);
        // Close any gap (also a rounding-level one) to the previous piece by a straight piece.
        if (before > first) {
          const Piece& prev = pieces_[before - 1];
          const Piece& next = pieces_[before];
          if (prev.u_end != next.u_start || prev.v_end != next.v_start) {
            pieces_.insert(pieces_.begin() + static_cast<std::ptrdiff_t>(before),
                           make_segment(prev.u_end, prev.v_end, next.u_start, next.v_start));
          }
        }
      }
    }
    if (pieces_.size() > first) {
      const Piece& last = pieces_.back();
      const Piece& head = pieces_[first];
      if (last.u_end != head.u_start || last.v_end != head.v_start) {
        pieces_.push_back(make_segment(last.u_end, last.v_end, head.u_start, head.v_start));
      }
    }
  }

  // 2. Grid box = domain ∩ the loops' bounding box: the region lies inside it.
  double lu = std::numeric_limits<double>::infinity(), hu = -lu, lv = lu, hv = -lu;
  for (const Piece& p : pieces_) {
    lu = std::min(lu, p.u_lo);
    hu = std::max(hu, p.u_hi);
    lv = std::min(lv, piece_v_min_cp(p));
    hv = std::max(hv, piece_v_max_cp(p));
  }
  du_ = {std::max(lu, dom_u.lo), std::min(hu, dom_u.hi)};
  dv_ = {std::max(lv, dom_v.lo), std::min(hv, dom_v.hi)};
  if (!(du_.width() > 0.0) || !(dv_.width() > 0.0)) {
    // The loops enclose no area of the domain: the empty region.
    cells_u_ = cells_v_ = 0;
    return;
  }
  // About 4 cells per piece along each side, so that most cells hold no loop.
  const int side = static_cast<int>(
      std::clamp<std::size_t>(4 * pieces_.size(), kMinCellsPerSide, kMaxCellsPerSide));
  cells_u_ = cells_v_ = side;
  inv_cell_u_ = cells_u_ / du_.width();
  inv_cell_v_ = cells_v_ / dv_.width();
  const double cell_w = du_.width() / cells_u_, cell_h = dv_.width() / cells_v_;
  // Margins: a piece marks every cell it comes within (rounding of the cell mapping) of.
  const double eps_u = 1e-6 * cell_w + 8 * DBL_EPSILON * (std::abs(du_.lo) + std::abs(du_.hi));
  const double eps_v = 1e-6 * cell_h + 8 * DBL_EPSILON * (std::abs(dv_.lo) + std::abs(dv_.hi));

  const std::size_t cells = static_cast<std::size_t>(cells_u_) * cells_v_;
  cell_class_.assign(cells, static_cast<std::uint8_t>(RegionClass::outside));
  // Boundary cells and row lists: each piece is subdivided (construction only) until its
  // sub-pieces' control boxes span at most two cells each way, so the marked cells hug the
  // curve instead of its whole control box.
  std::vector<std::pair<std::int32_t, std::int32_t>> row_entries;  // (row, piece)
  for (std::size_t k = 0; k < pieces_.size(); ++k) {
    mark_piece(pieces_[k].cw.data(), pieces_[k].degree, static_cast<std::int32_t>(k), 0, eps_u,
               eps_v, row_entries);
  }
  std::sort(row_entries.begin(), row_entries.end());
  row_entries.erase(std::unique(row_entries.begin(), row_entries.end()), row_entries.end());
  row_first_.assign(cells_v_ + 1, 0);
  for (const auto& [row, piece] : row_entries)
    ++row_first_[row + 1];
  for (int r = 0; r < cells_v_; ++r)
    row_first_[r + 1] += row_first_[r];
  row_pieces_.clear();
  for (const auto& [row, piece] : row_entries) {
    const Piece& p = pieces_[piece];
    row_pieces_.push_back({piece_v_lo(p), piece_v_hi(p), std::min(p.u_start, p.u_end),
                           std::max(p.u_start, p.u_end), piece});
  }

  // 3. Inside/outside of the other cells: one sweep per row along its centre line.
  std::vector<double> crossings;
  for (int j = 0; j < cells_v_; ++j) {
    const double vc = dv_.lo + (j + 0.5) * cell_h;
    crossings.clear();
    for (int q = row_first_[j]; q < row_first_[j + 1]; ++q) {
      const Piece& p = pieces_[row_pieces_[q].piece];
      if (vc >= piece_v_lo(p) && vc < piece_v_hi(p))
        crossings.push_back(crossing_u(p, vc, cell_w / 16));
    }
    std::sort(crossings.begin(), crossings.end());
    // The centres increase along the row: one walk over the sorted crossings counts those at or
    // left of each centre.
    std::size_t left = 0;
    for (int i = 0; i < cells_u_; ++i) {
      const double uc = du_.lo + (i + 0.5) * cell_w;
      while (left < crossings.size() && crossings[left] <= uc)
        ++left;
      std::uint8_t& c = cell_class_[static_cast<std::size_t>(i) * cells_v_ + j];
      if (c == static_cast<std::uint8_t>(RegionClass::boundary)) continue;
      const std::size_t right = crossings.size() - left;
      c = static_cast<std::uint8_t>(right % 2 == 1 ? RegionClass::inside : RegionClass::outside);
    }
  }

  // 4. Prefix sums: sums_[i * (cells_v_ + 1) + j] counts cells [0, i) x [0, j), modulo 2^16
  // (unsigned arithmetic wraps): half the memory of 32-bit sums, and exact for every box
  // of fewer than 2^16 cells, which is every box but the whole grid at the largest size.
  static_assert(kMaxCellsPerSide * kMaxCellsPerSide <= 65536);
  const int stride = cells_v_ + 1;
  sums_.assign(static_cast<std::size_t>(cells_u_ + 1) * stride, CellSums{});
  for (int i = 0; i < cells_u_; ++i) {
    std::uint16_t row_boundary = 0, row_inside = 0;  // cells [0, j] of row i
    for (int j = 0; j < cells_v_; ++j) {
      const std::uint8_t c = cell_class_[static_cast<std::size_t>(i) * cells_v_ + j];
      row_boundary += c == static_cast<std::uint8_t>(RegionClass::boundary);
      row_inside += c == static_cast<std::uint8_t>(RegionClass::inside);
      const CellSums& up = sums_[static_cast<std::size_t>(i) * stride + (j + 1)];
      CellSums& at = sums_[static_cast<std::size_t>(i + 1) * stride + (j + 1)];
      at.boundary = static_cast<std::uint16_t>(up.boundary + row_boundary);
      at.inside = static_cast<std::uint16_t>(up.inside + row_inside);
    }
  }
  std::int32_t boundary_total = 0, inside_total = 0;
  for (const std::uint8_t c : cell_class_) {
    boundary_total += c == static_cast<std::uint8_t>(RegionClass::boundary);
    inside_total += c == static_cast<std::uint8_t>(RegionClass::inside);
  }
  boundary_total_ = boundary_total;
  inside_total_ = inside_total;
}

// Marks the cells met by the homogeneous piece a[0..n] (or by its control box once that is
// small) as boundary and lists the piece in the rows it meets. A sub-piece left of the grid box
// is dropped (never right of a query point); one right of it (outside the domain) is listed in
// its rows (rays cross it) but marks no cell.
void TrimRegion::mark_piece(const Vec3* a, int n, std::int32_t piece, int depth, double eps_u,
                            double eps_v,
                            std::vector<std::pair<std::int32_t, std::int32_t>>& rows) {
  double u_lo = std::numeric_limits<double>::infinity(), u_hi = -u_lo, v_lo = u_lo, v_hi = -u_lo;
  for (int i = 0; i <= n; ++i) {
    const double u = euclid_u(a[i]), v = euclid_v(a[i]);
    u_lo = std::min(u_lo, u);
    u_hi = std::max(u_hi, u);
    v_lo = std::min(v_lo, v);
    v_hi = std::max(v_hi, v);
  }
  // A (sub-)piece within band_ of an edge of the grid box (CAD loops that run along the
  // domain's edge, often a few ulps off it) marks no cell: the region beside it is uniform up to
  // that band, so the cells there stay inside or outside and a patch along the edge is not
  // `boundary` for it. It stays in its rows' lists: contains() in boundary cells and the row
  // sweep count its crossings exactly (a piece along u = du_.lo crosses left of every cell
  // centre, one along du_.hi right of every one, one along v = dv_.lo or dv_.hi no centre line).
  const bool along_edge = u_hi <= du_.lo + band_ || u_lo >= du_.hi - band_ ||
                          v_hi <= dv_.lo + band_ || v_lo >= dv_.hi - band_;
  u_lo -= eps_u;
  u_hi += eps_u;
  v_lo -= eps_v;
  v_hi += eps_v;
  if (u_hi < du_.lo || v_hi < dv_.lo || v_lo > dv_.hi) return;
  const int j0 = cell_v(std::max(v_lo, dv_.lo)), j1 = cell_v(std::min(v_hi, dv_.hi));
  const bool right_of_box = u_lo > du_.hi;
  const int i0 = cell_u(std::max(u_lo, du_.lo)), i1 = cell_u(std::min(u_hi, du_.hi));
  if (right_of_box || along_edge || depth >= kMaxMarkDepth || (i1 - i0 <= 1 && j1 - j0 <= 1)) {
    for (int j = j0; j <= j1; ++j) {
      rows.emplace_back(j, piece);
      if (right_of_box || along_edge) continue;
      for (int i = i0; i <= i1; ++i)
        cell_class_[static_cast<std::size_t>(i) * cells_v_ + j] =
            static_cast<std::uint8_t>(RegionClass::boundary);
    }
    return;
  }
  Vec3 left[kMaxDegree + 1], right[kMaxDegree + 1];
  halve(a, 1, n, left, right);
  mark_piece(left, n, piece, depth + 1, eps_u, eps_v, rows);
  mark_piece(right, n, piece, depth + 1, eps_u, eps_v, rows);
}

std::size_t TrimRegion::piece_count() const {
  return pieces_.size();
}

bool TrimRegion::contains(double u, double v) const {
  if (cells_u_ == 0) return false;
  // Written so that NaN is outside. Within band_ of the grid box a point is on a loop to the
  // region's tolerance: it gets its edge cell's answer, as classify() assumes.
  if (!(u >= du_.lo - band_ && u <= du_.hi + band_ && v >= dv_.lo - band_ && v <= dv_.hi + band_))
    return false;
  const int j = cell_v(v);
  const std::uint8_t c = cell_class_[static_cast<std::size_t>(cell_u(u)) * cells_v_ + j];
  if (c != static_cast<std::uint8_t>(RegionClass::boundary)) {
    return c == static_cast<std::uint8_t>(RegionClass::inside);
  }
  bool inside = false;
  for (int q = row_first_[j]; q < row_first_[j + 1]; ++q) {
    const RowPiece& r = row_pieces_[q];
    if (!(v >= r.v_lo && v < r.v_hi)) continue;
    // crossing_right_of's own first tests, without opening the piece.
    if (u < r.u_min) {
      inside = !inside;
    } else if (!(u > r.u_max) && crossing_right_of(pieces_[r.piece], u, v)) {
      inside = !inside;
    }
  }
  return inside;
}

RegionClass TrimRegion::classify(double u0, double u1, double v0, double v1) const {
  if (std::isnan(u0) || std::isnan(u1) || std::isnan(v0) || std::isnan(v1)) {
    return RegionClass::boundary;
  }
  if (cells_u_ == 0 || u0 > u1 || v0 > v1) return RegionClass::outside;  // (empty box)
  if (u1 < du_.lo || u0 > du_.hi || v1 < dv_.lo || v0 > dv_.hi) return RegionClass::outside;
  // Parts of the box beyond the grid box (by more than band_) are outside the region.
  const bool beyond =
      u0 < du_.lo - band_ || u1 > du_.hi + band_ || v0 < dv_.lo - band_ || v1 > dv_.hi + band_;
  const int i0 = cell_u(std::max(u0, du_.lo)), i1 = cell_u(std::min(u1, du_.hi));
  const int j0 = cell_v(std::max(v0, dv_.lo)), j1 = cell_v(std::min(v1, dv_.hi));
  const int stride = cells_v_ + 1;
  const std::size_t a = static_cast<std::size_t>(i1 + 1) * stride + (j1 + 1);
  const std::size_t b = static_cast<std::size_t>(i0) * stride + (j1 + 1);
  const std::size_t c = static_cast<std::size_t>(i1 + 1) * stride + j0;
  const std::size_t d = static_cast<std::size_t>(i0) * stride + j0;
  const std::int32_t cells = (i1 - i0 + 1) * (j1 - j0 + 1);
  std::int32_t boundary = boundary_total_, in = inside_total_;
  if (cells < cells_u_ * cells_v_) {  // fewer than 2^16 cells: the wrapped sums are exact
    boundary = static_cast<std::uint16_t>(sums_[a].boundary - sums_[b].boundary -
                                          sums_[c].boundary + sums_[d].boundary);
    in = static_cast<std::uint16_t>(sums_[a].inside - sums_[b].inside - sums_[c].inside +
                                    sums_[d].inside);
  }
  if (boundary > 0) return RegionClass::boundary;
  if (in == 0) return RegionClass::outside;
  if (!beyond && in == cells) return RegionClass::inside;
  return RegionClass::boundary;
}

}  // namespace nurbsreg::engine
