#pragma once
// Internal: finer Bézier patches where a surface's own are far from flat. The search's bounds
// (each patch's oriented box) and its clipping both work best on patches that are nearly flat: a
// long twisted strip (the IEA blade's 8 m by 5 cm patches) or a high-degree patch wrapped a
// quarter turn around a rod (linkrods) has a box many times thicker than the surface, so a point
// near the surface lies in the boxes of many patches and each one's clipping takes many steps.
// Knot insertion cuts such spans into pieces: the same function of (u, v), the same entities,
// trim loops and orientation; only the patches the engine searches are smaller.

#include <vector>

#include "nurbsreg/engine/bezier.hpp"
#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/nurbs_surface.hpp"

namespace nurbsreg::engine {

// How far a patch is from flat: its oriented box's thickness (along the net's normal) over the
// smaller of its two other sides. 0 for a plane.
double patch_thickness_ratio(const BezierPatch& patch);

// Pieces per knot span, along u and along v, in the order of the surface's non-empty spans, whose
// ends are breaks_u and breaks_v; and the box of the surface's own Bézier patches' control points
// (what PreparedModel::bounds() reports: the model's size as given, whatever the search cuts).
struct SpanPieces {
  std::vector<int> u, v;
  std::vector<double> breaks_u, breaks_v;
  Aabb control_box;
};

// For every patch of the surface: pieces are doubled along u or v, whichever thins them more,
// while the thickest piece's ratio is above kFlatEnough, each doubling thins it by a clear
// margin (kWorthSplitting), and the patch has at most kMaxPieces pieces. A span gets the most
// pieces any of its patches asks for (knot lines run across the whole surface).
SpanPieces search_pieces(const NurbsSurface& surface);

// The surface with the knots that cut its spans into `pieces` (search_pieces of it) equal
// parameter pieces (itself when none is needed).
NurbsSurface refine_for_search(const NurbsSurface& surface, const SpanPieces& pieces);
inline NurbsSurface refine_for_search(const NurbsSurface& surface) {
  return refine_for_search(surface, search_pieces(surface));
}

inline constexpr double kFlatEnough = 0.3;
inline constexpr double kWorthSplitting = 0.8;
inline constexpr int kMaxPieces = 16;

}  // namespace nurbsreg::engine
