#pragma once
// Internal: the part of a WarmCertificate (projection.hpp) that lives on one patch. For an
// anchor point a whose closest point lies on patch P at local (s, t): a sub-box N of P around
// (s, t) on which F_q = |S - q|^2 is strictly convex for every q within `radius` of a, and a lower
// bound of F_a over the rest of P. The projector adds the rest of the model (its own search).

#include <algorithm>
#include <cstdint>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/surface_projection.hpp"

namespace nurbsreg::engine {

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
// bounded against (d + 2 radius)^2 where d = |S(s, t) - a|. A rational patch: interior feet only,
// convexity of G = N_q - m D for every value m a query's proof can meet (the .cpp). Uses the
// scratch's first 28 grids (a polynomial patch: 11); no heap allocation.
// On a trimmed face (region not null) only boxes N that the region proves inside it are tried
// (box_in_region), down to half-width 1/25: every point of N is then a point of the face, so
// N's minimum is the face's there, and P outside N is bounded as untrimmed (a lower bound of
// its face part too). The face's trim edges are items of the search like the other faces.
PatchCertificate certify_patch(const PreparedPatch& pp, const Vec3& a, double s, double t, double d,
                               double r_max, SurfaceScratch& scratch,
                               const TrimRegion* region = nullptr);

// How G = N_q - m D of a rational patch moves with the query on a box N (certify_patch's rational
// proof): bounds on the norms of the second differences of E' = E - (a - o) D and of D on N's own
// grids (each restricted to N: its Bernstein coefficients there), for an anchor a. Restricting
// first matters: on a long cylinder strip (NIST's and linkrods' bores, hundreds of mm long against
// radii of a few) E' is w (P - a), whose second differences along the arc carry the control rows'
// axial offset from the anchor: the whole patch's, scaled by N's widths, carry the strip's full
// length, N's rows only N's. Rounding: the restricted values are sums of the grid's coefficients,
// good to a few ulps of the largest one; 1e-12 of it is added. Uses the scratch's first nine grids.
struct BoxDifferences {
  double e_ss = 0.0, e_tt = 0.0, e_st = 0.0, d_ss = 0.0, d_tt = 0.0, d_st = 0.0;
};
BoxDifferences rational_box_differences(const PreparedPatch& pp, const Vec3& a, double s0,
                                        double s1, double t0, double t1, SurfaceScratch& scratch);

// Is every point of patch pp's local box [s0, s1] x [t0, t1] in the region (proven: the
// region's classify, on the box's parameters widened by their rounding)? True without a region.
bool box_in_region(const TrimRegion* region, const BezierPatch& bp, double s0, double s1, double t0,
                   double t1);

// A box N that reaches into the neighbours of the anchor's foot patch P (same surface, which
// must be surface_c1): N is given in P's grid coordinates, where the patch i spans after P in u
// and j in v covers [i, i + 1] x [j, j + 1] (P itself [0, 1]^2). Its part of that patch, in the
// patch's local parameters ("piece"): [max(0, s0 - i), min(1, s1 - i)] x (the same in t), false
// when N does not overlap the patch's interior. Computed in double from N's floats (exact), the
// same way where a certificate is made and where it is used.
inline bool span_piece(float s0, float s1, float t0, float t1, int i, int j, double& ps0,
                       double& ps1, double& pt0, double& pt1) {
  if (!(double(s0) < i + 1.0 && double(s1) > i && double(t0) < j + 1.0 && double(t1) > j)) {
    return false;
  }
  ps0 = std::max(0.0, double(s0) - i);
  ps1 = std::min(1.0, double(s1) - i);
  pt0 = std::max(0.0, double(t0) - j);
  pt1 = std::min(1.0, double(t1) - j);
  return true;
}

struct SpanCertificate {
  // The most patches N may reach beyond P on each side (ProjectionOptions::certificate_span).
  static constexpr int kReach = kMaxCertificateSpan;
  static constexpr int kMaxPatches = (2 * kReach + 1) * (2 * kReach + 1);
  float s0 = 0.0f, s1 = 1.0f, t0 = 0.0f, t1 = 1.0f;  // N in P's grid coordinates
  double radius = 0.0;                               // 0: no certificate
  // Lower bound of F_a on the overlapped patches outside N, at most (d + 2 radius)^2.
  double outside_sq = 0.0;
  int count = 0;  // the patches N overlaps (their clipping minima are not the clearance's)
  std::int64_t patches[kMaxPatches] = {};
};

// certify_patch's proof on a box N of half-widths half_s, half_t (in P's local units, at most
// `reach`) around the foot (s, t), clipped to the surface's grid (the patches that exist, at most
// `reach` <= kReach beyond P on each side): F_q strictly convex on every piece of N
// for every q within the radius of a (then on N: the surface is C1), or, for a foot on the
// surface's own edge or corner, F_q increasing away from it on every piece and convex along it.
// Gives up (radius 0) as soon as it cannot serve moves beyond `floor`: radius <= floor, or the
// overlapped patches within d + 2 floor of a. Polynomial patches only; on a trimmed face every
// piece of N must be proven inside the region (box_in_region). Uses the scratch's first 12
// grids and one more per patch N overlaps (each patch's grid of F made once); no heap
// allocation.
SpanCertificate certify_span(const PreparedModel& model, std::size_t patch, const Vec3& a, double s,
                             double t, double d, double r_max, double half_s, double half_t,
                             double floor, int reach, SurfaceScratch& scratch);

// The minimum of F_p over a certificate's box N (WarmCertificate: anchor patch `anchor_patch`,
// N = [s0, s1] x [t0, t1] in its grid coordinates), by Newton piece by piece: from (s, t) on the
// piece of `patch`, then, while the piece's minimum lies on a side that N continues across, on
// the neighbouring pieces that touch it, moving to one with a smaller minimum. With F convex on
// N (or increasing away from the surface's edge and convex along it), a piece's minimum that no
// touching piece improves is N's minimum. On return patch, s, t, foot and normal are that
// minimum's; `stationary` is false when a Newton did not settle or the moves ran out (then the
// point is only an upper bound). Returns the squared distance. `predict`: (s, t) is the foot of
// a point far from p (a certificate borrowed from another point): on an N that spans patches,
// Newton then starts where the tangent plane at (s, t) puts p's foot, on the piece that holds
// it, rather than walking there piece by piece.
double newton_on_certificate_box(const PreparedModel& model, std::int64_t anchor_patch, float s0,
                                 float s1, float t0, float t1, const Vec3& p, std::int64_t& patch,
                                 double& s, double& t, Vec3& foot, Vec3& normal, bool& stationary,
                                 bool predict = false);

}  // namespace nurbsreg::engine
