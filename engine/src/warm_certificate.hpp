#pragma once
// Internal: the part of a WarmCertificate (projection.hpp) that lives on one patch. For an
// anchor point a whose closest point lies on patch P at local (s, t): a sub-box N of P around
// (s, t) on which F_q = |S - q|^2 is strictly convex for every q within `radius` of a, and a lower
// bound of F_a over the rest of P. The projector adds the rest of the model (its own search).

#include "nurbsreg/engine/surface_projection.hpp"

namespace nurbsreg::engine {

// Defined in surface_clipping.cpp beside the clipping's convexity test, which it shares: the
// largest r <= r_max (bisection, rounded down) such that the test holds on the coefficient grid
// `n` (F_a on some box) for every q with |q - a| <= r, given bounds on the norms of the box's E
// second differences (s, t, mixed); 0 when it fails at a itself. Polynomial patches only.
double grid_convexity_radius(const double* n, int rows, int cols, double e_ss, double e_tt,
                             double e_st, double r_max);

// newton_on_patch on a box where F is proven strictly convex (a certificate's N): a Newton step
// below 1e-10 of the parameter range counts as converged without being taken, which saves the
// last evaluation.
double newton_in_certified_box(const BezierPatch& patch, const Vec3& p, double s0, double s1,
                               double t0, double t1, double& s, double& t, Vec3& foot, Vec3* normal,
                               bool* converged);

struct PatchCertificate {
  // N in P's local parameters, as floats (compact in hints); every test was made on exactly
  // these values.
  float s0 = 0.0f, s1 = 1.0f, t0 = 0.0f, t1 = 1.0f;
  double radius = 0.0;  // 0: no certificate
  // Lower bound of F_a on P outside N (infinity when N is all of P), at most the `target_sq`
  // asked for (the bound is refined only up to it).
  double outside_sq = 0.0;
};

// Tries N = all of P, then boxes of local half-width 1/4 and 1/10 around (s, t); the first on which
// the convexity test holds (or, for a foot on P's edge or corner, F increasing away from it and
// convex along it: edge_radius in the .cpp) is kept, with radius <= r_max, and P outside it is
// bounded against (d + 2 radius)^2 where d = |S(s, t) - a|. Polynomial patches only (radius 0
// otherwise). Uses the scratch's first four grids; no heap allocation.
PatchCertificate certify_patch(const PreparedPatch& pp, const Vec3& a, double s, double t, double d,
                               double r_max, SurfaceScratch& scratch);

}  // namespace nurbsreg::engine
