#include "model/search_refinement.hpp"

#include <algorithm>

#include "model/patch_frame.hpp"
#include "nurbsreg/engine/decompose.hpp"

namespace nurbsreg::engine {
namespace {

// The largest thickness ratio over the patch cut into pu x pv equal parameter pieces.
double pieces_ratio(const BezierPatch& patch, int pu, int pv) {
  double worst = 0.0;
  BezierPatch rest_u = patch, column, rest_v, piece, next;
  for (int a = 0; a < pu; ++a) {
    if (a + 1 < pu) {
      rest_u.split_u(1.0 / (pu - a), column, next);
      rest_u = next;
    } else {
      column = rest_u;
    }
    rest_v = column;
    for (int b = 0; b < pv; ++b) {
      if (b + 1 < pv) {
        rest_v.split_v(1.0 / (pv - b), piece, next);
        rest_v = next;
      } else {
        piece = rest_v;
      }
      worst = std::max(worst, patch_thickness_ratio(piece));
    }
  }
  return worst;
}

// Interior knots cutting each non-empty span [breaks[k], breaks[k + 1]] into pieces[k].
std::vector<double> cuts(const std::vector<double>& breaks, const std::vector<int>& pieces) {
  std::vector<double> knots;
  for (std::size_t k = 0; k < pieces.size(); ++k) {
    const double lo = breaks[k], hi = breaks[k + 1];
    for (int j = 1; j < pieces[k]; ++j)
      knots.push_back(lo + (hi - lo) * j / pieces[k]);
  }
  return knots;
}

}  // namespace

double patch_thickness_ratio(const BezierPatch& patch) {
  Vec3 axis[3];
  oriented_axes(patch, axis);
  double lo[3], hi[3];
  extents_along(patch, axis, lo, hi);
  const double width = std::min(hi[0] - lo[0], hi[1] - lo[1]);
  return width > 0.0 ? (hi[2] - lo[2]) / width : 0.0;
}

SpanPieces search_pieces(const NurbsSurface& surface) {
  int spans_u = 0, spans_v = 0;
  const std::vector<BezierPatch> patches = decompose(surface, &spans_u, &spans_v);
  SpanPieces pieces{std::vector<int>(spans_u, 1), std::vector<int>(spans_v, 1), {}, {}, {}};
  for (const BezierPatch& patch : patches)
    pieces.control_box.extend(bounding_box(patch));
  for (int a = 0; a < spans_u; ++a)
    pieces.breaks_u.push_back(patches[static_cast<std::size_t>(a) * spans_v].param_u.lo);
  for (int b = 0; b < spans_v; ++b)
    pieces.breaks_v.push_back(patches[static_cast<std::size_t>(b)].param_v.lo);
  if (!patches.empty()) {
    pieces.breaks_u.push_back(patches.back().param_u.hi);
    pieces.breaks_v.push_back(patches.back().param_v.hi);
  }
  for (int a = 0; a < spans_u; ++a) {
    for (int b = 0; b < spans_v; ++b) {
      const BezierPatch& patch = patches[static_cast<std::size_t>(a) * spans_v + b];
      int pu = 1, pv = 1;
      double ratio = patch_thickness_ratio(patch);
      while (ratio > kFlatEnough && 2 * pu * pv <= kMaxPieces) {
        const double along_u = pieces_ratio(patch, 2 * pu, pv);
        const double along_v = pieces_ratio(patch, pu, 2 * pv);
        const double thinner = std::min(along_u, along_v);
        if (!(thinner < kWorthSplitting * ratio)) break;
        (along_u <= along_v ? pu : pv) *= 2;
        ratio = thinner;
      }
      pieces.u[a] = std::max(pieces.u[a], pu);
      pieces.v[b] = std::max(pieces.v[b], pv);
    }
  }
  return pieces;
}

NurbsSurface refine_for_search(const NurbsSurface& surface, const SpanPieces& pieces) {
  const std::vector<double> cuts_u = cuts(pieces.breaks_u, pieces.u);
  const std::vector<double> cuts_v = cuts(pieces.breaks_v, pieces.v);
  if (cuts_u.empty() && cuts_v.empty()) return surface;
  NurbsSurface out = cuts_u.empty() ? surface : refine_knots_u(surface, cuts_u);
  if (!cuts_v.empty()) out = refine_knots_v(out, cuts_v);
  return out;
}

}  // namespace nurbsreg::engine
