#pragma once
// Internal: the box-constrained Newton on the surface geometry that finishes every clipping box
// (newton_on_patch in surface_projection.hpp is its public form).

#include <limits>

#include "nurbsreg/engine/surface_projection.hpp"

namespace nurbsreg::engine {

// The patch a Newton runs on, with whether its weights are all exactly 1 (then the homogeneous
// sums are the derivatives). A prepared patch knows it; a bare one is read once per Newton
// rather than at every evaluation (36 weights of a (3, 8) patch cost a sixth of one).
struct NewtonPatch {
  NewtonPatch(const PreparedPatch& prepared)
      : patch(prepared.patch), unit_weights(prepared.unit_weights) {}
  NewtonPatch(const BezierPatch& bare);
  const BezierPatch& patch;
  bool unit_weights;
};

// newton_on_patch with an optional early exit for a box on which F = |S - p|^2 is known to be
// convex (`abort_at` finite, polynomial patches only): a convex F lies above its tangent plane,
// so F >= F(x) + grad F(x) . (y - x) >= F(x) + Σ min over the box's ends, for every y in the box.
// When that bound reaches abort_at the box cannot beat the caller's best: Newton stops and
// returns +infinity (nothing to offer; s, t and foot are then meaningless).
double newton_core(const NewtonPatch& on, const Vec3& p, double s0, double s1, double t0, double t1,
                   double& s, double& t, Vec3& foot, SurfaceProjectionStats* stats, Vec3* normal,
                   double abort_at, bool* converged = nullptr, double settled_step = 1e-15);

// newton_on_patch for a caller that proves its KKT point the answer by other means (a
// certificate's N, where F is strictly convex; the model's reach bounds): a Newton step below
// 1e-10 of the parameter range counts as converged without being taken, which saves the last
// evaluation (the point is then that close to the minimiser, F within ~|H| 1e-20 of it).
double newton_to_proven_point(const NewtonPatch& on, const Vec3& p, double s0, double s1, double t0,
                              double t1, double& s, double& t, Vec3& foot, Vec3* normal,
                              bool* converged);

// S, S_s and S_t at local (s, t) (out[0..2]) from the unrolled first-derivative kernel of the
// patch's degrees; false (nothing written) when they have none: a full evaluation would cost as
// much as a Newton iteration.
bool patch_tangents(const NewtonPatch& on, double s, double t, Vec3* out);

}  // namespace nurbsreg::engine
