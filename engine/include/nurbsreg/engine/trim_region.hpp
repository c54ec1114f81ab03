#pragma once
// The trimmed region of a face in its (u, v) parameter space, prepared for fast, exact
// point-in-region queries and conservative box classification; and the 3-D boundary edges of a
// trimmed face.
//
// The region is the even-odd interior of the surface's trim loops (NurbsSurface::trim_loops),
// intersected with the surface's domain. Gaps between consecutive curves of a loop (and between
// its last and first curve) are closed by straight segments in (u, v).
//
// Built once (allocates); afterwards immutable, and every query is const, thread-safe and free of
// heap allocation.

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "nurbsreg/engine/nurbs_curve.hpp"
#include "nurbsreg/engine/nurbs_surface.hpp"
#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine {

enum class RegionClass : std::uint8_t {
  outside,   // no point of the box is in the region
  inside,    // every point of the box is in the region
  boundary,  // the box may meet a loop (conservative: may also be returned for a uniform box)
};

class TrimRegion {
 public:
  TrimRegion() = default;  // the empty region (contains nothing)
  // Throws std::invalid_argument when the surface has no trim loops or a loop is invalid.
  explicit TrimRegion(const NurbsSurface& surface);

  // Is (u, v) in the region? Exact up to rounding: a precomputed grid answers at once for points
  // away from the loops; near a loop, the crossings of a ray with the loops' monotone rational
  // Bézier pieces are counted exactly (a bracketing root search on the piece, not a polygon).
  // Points outside the surface's domain are outside. A point on a loop (within about 1e-13 of
  // the parameter space's scale: the tolerance to which the loops are split and chained) may get
  // either answer; so may a point within that tolerance of the domain's edge, or of the loops'
  // bounding box, where a loop runs along it. NaN is outside.
  bool contains(double u, double v) const;

  // Conservative classification of the closed box [u0, u1] x [v0, v1]: outside and inside are
  // proofs (consistent with contains() at every point of the box), boundary is "don't know".
  // O(1) (prefix sums over the grid). An empty box (u0 > u1) is outside; NaN gives boundary.
  RegionClass classify(double u0, double u1, double v0, double v1) const;

  // Number of monotone Bézier pieces the loops were split into (diagnostics, tests).
  std::size_t piece_count() const;

  struct Piece;  // a rational Bézier piece of a loop, monotone in u and v (defined below)

 private:
  // Grid box: the domain intersected with the loops' bounding box (the region lies inside it).
  ParamInterval du_, dv_;
  // Grid of cells over the grid box; see trim_region.cpp.
  int cells_u_ = 0, cells_v_ = 0;
  double inv_cell_u_ = 0.0, inv_cell_v_ = 0.0;  // cells per unit of u, v
  double band_ = 0.0;  // the loops' tolerance (1e-13 x the parameter space's scale)
  std::vector<std::uint8_t> cell_class_;  // RegionClass per cell, [iu * cells_v_ + iv]
  // 2-D prefix sums of boundary and inside cells, modulo 2^16 (see classify), and the whole
  // grid's exact counts.
  struct CellSums {
    std::uint16_t boundary = 0, inside = 0;
  };
  std::vector<CellSums> sums_;
  std::int32_t boundary_total_ = 0, inside_total_ = 0;
  std::vector<Piece> pieces_;
  // Per grid row (v band): the pieces whose v range meets it, for the exact crossing count, as
  // compact records side by side: a point in a boundary cell reads its row's ranges in one run
  // and opens a piece (hundreds of bytes) only when its u falls within the piece's u range.
  struct RowPiece {
    double v_lo = 0.0, v_hi = 0.0;    // the piece's v range, half-open [v_lo, v_hi)
    double u_min = 0.0, u_max = 0.0;  // its end points' u range (the piece is monotone)
    std::int32_t piece = 0;
  };
  std::vector<std::int32_t> row_first_;
  std::vector<RowPiece> row_pieces_;

  int cell_u(double u) const;
  int cell_v(double v) const;
  // Construction: marks boundary cells and lists (row, piece) pairs for one piece.
  void mark_piece(const Vec3* cw, int degree, std::int32_t piece, int depth, double eps_u,
                  double eps_v, std::vector<std::pair<std::int32_t, std::int32_t>>& rows);
};

// Private to TrimRegion (defined here so that TrimRegion stays an ordinary copyable value).
// Homogeneous control points (w u, w v, w), w > 0, whose u and v coordinates are monotone: by
// the variation-diminishing property the piece is monotone in u and v, so a line v = const
// meets it at most once and the u range of any part of it is that of the part's end points.
struct TrimRegion::Piece {
  double v_start = 0.0, v_end = 0.0;  // v at t = 0 and t = 1 (shared exactly with neighbours)
  double u_start = 0.0, u_end = 0.0;
  double u_lo = 0.0, u_hi = 0.0;  // control-point bounds in u
  int degree = 1;
  std::array<Vec3, kMaxDegree + 1> cw{};
  std::array<Vec3, kMaxDegree + 1> cb{};  // C(degree, i) cw[i], for Horner evaluation
};

// The 3-D boundary edges of a trimmed surface, one per trim curve, in loop order:
// trim_loops[l].curves[c].edge when given; otherwise the exact 3-D image S(uv(t)) of a degree-1
// uv curve as a rational B-spline (split where the line crosses the surface's knot lines; on
// each piece S(uv(t)) is a rational polynomial of degree degree_u + degree_v, whose Bernstein
// coefficients are computed exactly as sums of products of non-negative restricted Bernstein
// polynomials: see trim_edges.cpp; a piece along an iso line has the lower degree). C0 joints;
// each edge has the same parameter domain as its uv curve. Measured deviation from
// S(uv(t)): below 1e-13 x the surface's bounding diagonal (tests/engine/trim_edges_test.cpp).
// Throws std::invalid_argument when a computed edge would exceed kMaxDegree, or when a uv curve
// of degree > 1 has no edge. Allocates; run once per model.
struct TrimEdge {
  int loop = 0, curve = 0;  // indices into NurbsSurface::trim_loops
  NurbsCurve edge;          // 3-D, domain == uv curve's domain
};
std::vector<TrimEdge> trim_edges(const NurbsSurface& surface);

}  // namespace nurbsreg::engine
