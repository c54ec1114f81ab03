#pragma once
// The box of a model's actual geometry: trimmed faces as trimmed (not their untrimmed surfaces),
// the faces' trim edges and the model's curves (issue 26, item 4).
//
// PreparedModel::bounds() is the box of every Bézier patch's control points, trimmed away or not:
// right for the hierarchy, but far too large as "the size of the model" for CAD parts whose faces
// are small pieces of large surfaces (linkrods.step: diagonal 46.3 against about 5.6 for its
// faces). The box here is what scan-size checks and size-derived defaults should use.
//
// Method (model_bounds.cpp): for each of the six directions +-x, +-y, +-z, a best-first branch
// and bound over the model's Bézier patches (the face's part only: sub-patches the trim region
// proves to be outside are dropped, TrimRegion::classify, refined below the region's grid by an
// exact test against the loops' own Bézier pieces), trim-edge pieces and curve pieces. A
// sub-patch's upper bound is its control points' extreme (convex hull property, widened for
// rounding); its corners, when in the face, are model points and give the lower bound. The node
// with the highest upper bound is split (de Casteljau, always restricted from the original patch
// so that rounding does not accumulate) until it is within the tolerance of the best model point
// found, or the node budget is spent. A sub-patch (or iso segment) whose coordinate is strictly
// monotone along s or t (its control points say so) is replaced by its side where the coordinate
// is largest: the face's largest value in it lies there or on a trim edge, which is an item of
// its own (so a face cut by a straight trim line along the top of a cylinder costs a handful of
// nodes, not one per tolerance-sized piece of the loop).
//
// Result: `box` is proven to contain every point of the geometry the engine projects onto (up to
// floating-point rounding, which is covered by a margin of about 1e-14 x the coordinates), with
// one assumption: the face's points on its loops are those of its 3-D trim edges (the engine's
// edges; a CAD file's edges agree with S(uv(t)) to its tolerance, cad_import.hpp). Each side lies
// at most `excess` beyond a model point that was found (`witnessed`). Allocates; run
// once per model. Deterministic, single-threaded.

#include <cstddef>
#include <vector>

#include "nurbsreg/engine/bounds.hpp"

namespace nurbsreg::engine {

class PreparedModel;

struct ModelBounds {
  Aabb box;        // proven: contains every trimmed face, trim edge and curve of the model
  Aabb witnessed;  // the box of model points found: witnessed <= true box <= box
  // Largest distance of a side of `box` from the same side of `witnessed`: the box is at most
  // this much larger than the geometry on any side.
  double excess = 0.0;
  // The sides are attained by model points up to rounding (excess within the rounding margin).
  bool exact = false;
  std::size_t nodes = 0;      // sub-patches and sub-pieces evaluated (cost)
  bool budget_spent = false;  // the node budget ran out before the tolerance was reached

  // "exact" or "proven bound" (for reports: `nurbsreg info`).
  const char* kind() const { return exact ? "exact" : "proven bound"; }
};

struct ModelBoundsOptions {
  // Stop refining a side once it is within this fraction of the witnessed box's diagonal of a
  // model point.
  double relative_tolerance = 1e-6;
  // Sub-patch / sub-piece evaluations per direction, at most (the cost cap: about 1-10 us
  // each, more for high degrees).
  std::size_t max_nodes_per_direction = 20000;
};

// The bound of the whole model. Empty box when the model has no geometry left (every face trimmed
// away).
ModelBounds compute_model_bounds(const PreparedModel& model,
                                 const ModelBoundsOptions& options = {});

// The bound of surface s's trimmed face and its trim edges only (`nurbsreg info`'s per-face
// boxes). The tolerance is relative to the face's own witnessed box.
ModelBounds compute_surface_bounds(const PreparedModel& model, int surface,
                                   const ModelBoundsOptions& options = {});

}  // namespace nurbsreg::engine
