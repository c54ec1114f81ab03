#pragma once
// Exact point projection and point inversion for NURBS surfaces.
//
// Two strategies:
//  - spherical_clipping (default): seed paper 001 (Chen et al. 2009) extended to rational patches.
//    The squared distance F(s, t) = |S(s, t) - p|^2 of a rational Bézier patch of degree (p, q)
//    is a rational Bézier function of degree (2p, 2q) (DESIGN.md "Projection: surfaces"); its
//    coefficients are subdivided by de Casteljau, sub-patches are eliminated by Theorem 1, an edge
//    criterion (Theorem 2 for polynomial patches; for rational ones, a proven sign of F_s or F_t)
//    hands a sub-patch to a 1-D clipping of its edge, and a sub-patch on which F is provably
//    strictly convex is finished by a box-constrained Newton on the surface geometry. Minima on
//    edges, corners, seams and poles are found; a depth limit is only a counted safety net.
//  - ma_hewitt: seed paper 000 (Ma & Hewitt 2003), Algorithms 2, 4, 6 and §8, as a comparison.
//    Its Theorem 1 is not valid in 3-D (seed 001 ref. [1]); it can return a wrong point.
//
// Prepared forms (PreparedPatch, SurfaceProjector) are immutable after construction; every query
// is const and thread-safe. Per-thread working memory lives in a SurfaceScratch, so the per-point
// hot path performs no heap allocation (SurfaceScratch allocates once in its constructor; it only
// grows if a surface has more than SurfaceScratch::kDefaultPatchCapacity patches).

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "nurbsreg/engine/bezier.hpp"
#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/nurbs_surface.hpp"
#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine {

class TrimRegion;

// A closest point: (u, v) in the PARENT surface's parameters.
struct SurfaceHit {
  double u = 0, v = 0;
  double distance_sq = std::numeric_limits<double>::infinity();
  Vec3 foot = Vec3::Zero();
  // Local (s, t) in [0, 1]^2 of the Bézier patch that produced the hit (set by
  // project_onto_patch; meaningless for a hit made elsewhere, e.g. from a hint).
  double s = 0, t = 0;
  // Unit S_s x S_t of that patch at the foot (from the last Newton evaluation), zero where it is
  // undefined within rounding (poles) or unknown.
  Vec3 normal = Vec3::Zero();
};

// One Bézier patch with everything a query needs, built once (allocates) by prepare_patch.
// The squared-distance coefficients for a point p are, with q = p - origin,
//   N_ij = G_ij - 2 q·E_ij + |q|^2 D_ij,   F = Σ B B N_ij / Σ B B D_ij,
// a few flops each. G and E are relative to `origin` (the bounding-sphere centre) so that points
// far from the world origin do not lose digits to cancellation.
struct PreparedPatch {
  BezierPatch patch;
  Aabb box;
  BoundingSphere sphere;
  Vec3 origin = Vec3::Zero();
  bool rational = false;      // false: all weights equal, D_ij == 1 exactly (F is a polynomial)
  bool unit_weights = false;  // every weight exactly 1 (the Newton's derivatives need no quotient)
  int rows = 0;               // 2 * degree_u + 1
  int cols = 0;               // 2 * degree_v + 1
  std::vector<double> d;      // D_ij at [i * cols + j]
  std::vector<double> g;      // G_ij
  std::vector<Vec3> e;        // E_ij
  std::vector<double> e_soa;  // E_ij again as x block, y block, z block (vectorised numerator)
  // Largest Euclidean norms of E's second differences in s, in t and mixed (polynomial patches):
  // moving the point by e changes N's second differences by -2 e . (those of E), at most
  // 2 |e| times these (warm certificates, warm_certificate.cpp).
  double e_ss = 0.0, e_tt = 0.0, e_st = 0.0;
  // The same for E's first differences in s and in t (the certificates' monotone edge test).
  double e_s = 0.0, e_t = 0.0;
  // Largest absolute second differences of D in s, in t and mixed (0 for polynomial patches):
  // the rational certificates' quick widening, tried before the one on the box's own grids
  // (warm_certificate.cpp).
  double d_ss = 0.0, d_tt = 0.0, d_st = 0.0;

  const BezierPatch& bezier() const { return patch; }
  // N_ij for the point p into out[rows * cols].
  void numerator(const Vec3& p, double* out) const;
};

PreparedPatch prepare_patch(const BezierPatch& patch);

// Per-thread working memory: a fixed-capacity stack of sub-patch coefficient grids (numerator and
// denominator) and of boundary rows. Default-constructible, reusable; allocates only here.
struct SurfaceScratch {
  static constexpr int kMaxDepth = 64;  // binary subdivisions of one patch (safety net)
  static constexpr int kStackCapacity = 2 * kMaxDepth + 8;
  static constexpr int kGridCapacity = (2 * kMaxDegree + 1) * (2 * kMaxDegree + 1);
  static constexpr int kDefaultPatchCapacity = 4096;

  SurfaceScratch();

  struct Box {
    double s0, s1, t0, t1;  // local box in the prepared patch's [0, 1]^2
    double lower;           // lower bound of F on the box (min of the ratio coefficients)
    double upper;           // max of the ratio coefficients
    int arg;                // index of the smallest ratio coefficient; -1: not computed yet
    int depth;
    // Trimmed patches only: the box may meet a trim loop (every box of an untrimmed patch, and
    // every box proven inside the region, has false).
    bool straddling;
  };
  std::vector<double> grids;  // kStackCapacity entries of 2 * kGridCapacity doubles (N then D)
  std::vector<Box> boxes;
  std::vector<double> rows;  // 1-D stack: entries of N and D rows, 2 (2 kMaxDegree + 1) each
  struct Interval {
    double t0, t1, lower;
    int depth;
  };
  std::vector<Interval> intervals;
  std::vector<std::pair<double, int>> order;  // patch visiting order (lower bound, index)
};

struct SurfaceProjectionStats {
  long subdivisions = 0;         // sub-patch (and boundary interval) splits
  long newton_iterations = 0;    // iterations of the box-constrained Newton on the geometry
  long depth_limit_hits = 0;     // sub-patches finished by the depth limit, not by a proof
  long patches_visited = 0;      // patches on which the per-patch algorithm ran
  long eliminations = 0;         // sub-patches dropped by Theorem 1
  long convex_terminations = 0;  // sub-patches finished because F is provably convex there
  long boundary_reductions = 0;  // sub-patches handed to their edge by Theorem 2
  // Sub-patches on which F's coefficients vary less than their rounding bound (points on or
  // very near the surface, poles): finished by Newton on the geometry.
  long resolution_terminations = 0;
  // Trimmed patches: sub-patches proven outside the region and dropped, and candidates (corner
  // values, Newton points) rejected because they lie outside it.
  long region_drops = 0;
  long region_rejections = 0;
  void add(const SurfaceProjectionStats& o);
};

enum class SurfaceStrategy { spherical_clipping, ma_hewitt };

// Exact projection onto one patch (spherical clipping): if the patch holds a point with squared
// distance < best.distance_sq, replaces best by the patch's closest point ((u, v) in the parent
// surface) and returns true; otherwise leaves best unchanged and returns false. const inputs;
// thread-safe with one scratch per thread; no heap allocation. A p with a NaN/inf coordinate
// returns false.
// Accuracy: a sub-patch is dropped only when its Bézier lower bound, lowered by a bound on the
// rounding of the coefficients (1e-14 (R + |p - c|)^2, R and c the bounding sphere), shows it
// cannot be closer than the best so far minus 1e-11 R in distance; the answer is a Newton
// stationary point on the geometry. Improvements below 1e-11 R are not pursued.
// (guess_s, guess_t): optional local guess of the minimiser (warm start, e.g. the previous foot);
// it only chooses where Newton starts on a box that holds it, never what is eliminated. NaN: none.
// region: null for an untrimmed patch or one proven inside its face's trimmed region (the hot
// path, unchanged). Otherwise the patch may straddle a trim loop of `region` (the region of the
// patch's parent surface, queried in the parent's (u, v)): the result is then the closest point
// of the patch among (a) the critical points and patch-boundary points that lie INSIDE the region
// -- every reported point satisfies region->contains(u, v) -- and it is exact provided the caller
// also projects onto the face's trim edges (the closest point of patch ∩ region lies in the
// region's interior or on a loop; the clipping proves nothing about loop points, the edges cover
// them). See Clipper in surface_clipping.cpp for the proofs.
bool project_onto_patch(const PreparedPatch& patch, const Vec3& p, SurfaceHit& best,
                        SurfaceScratch& scratch, SurfaceProjectionStats* stats = nullptr,
                        double guess_s = std::numeric_limits<double>::quiet_NaN(),
                        double guess_t = std::numeric_limits<double>::quiet_NaN(),
                        const TrimRegion* region = nullptr);

// Ma & Hewitt (seed 000) on one patch: Algorithm 6 with Algorithms 2 and 4, candidates refined
// by Newton on the flat sub-patch (§9). Not exact (see header comment). Same contract otherwise.
bool project_onto_patch_ma_hewitt(const PreparedPatch& patch, const Vec3& p, SurfaceHit& best,
                                  SurfaceProjectionStats* stats = nullptr);

// Box-constrained Newton minimisation of |S(s, t) - p|^2 on a Bézier patch over the local box
// [s0, s1] x [t0, t1] (s0 == s1 or t0 == t1 allowed: a boundary curve), starting at (s, t).
// Returns the squared distance; (s, t) and foot are updated. Descent only: never returns a value
// above the start value.
// normal (optional): the unit normal S_s x S_t at the result, or zero where undefined
// (|S_s x S_t| <= 1e-12 |S_s| |S_t|), from the derivatives Newton already has.
// converged (optional): set to true when the iteration ended at a stationary (KKT) point of the
// box, false when it stopped otherwise (iteration cap, failed line search, non-finite step).
double newton_on_patch(const BezierPatch& patch, const Vec3& p, double s0, double s1, double t0,
                       double t1, double& s, double& t, Vec3& foot,
                       SurfaceProjectionStats* stats = nullptr, Vec3* normal = nullptr,
                       bool* converged = nullptr);

// A certificate for warm starts: true when F = |S - p|^2 is provably strictly convex over the
// whole patch (Bézier bounds on its second derivatives; for a rational patch, on every
// G_c = N - c D, as in the clipping's termination test). Then a KKT point of F on the patch (a
// converged newton_on_patch over [0, 1]^2) is the patch's global minimum, and the clipping of the
// patch can be skipped. Uses the scratch's first grid; no heap allocation.
bool squared_distance_convex(const PreparedPatch& patch, const Vec3& p, SurfaceScratch& scratch);

// converged: the closest point was found; skipped_nonfinite: the point has a NaN or infinite
// coordinate (the same name in every status enum of the engine); no_candidate: the strategy
// produced no point at all (only ma_hewitt can: its Theorem 1 may discard every patch of a closed
// surface).
enum class SurfaceProjectionStatus : std::uint8_t { converged, skipped_nonfinite, no_candidate };

// One batch result (written by index).
struct SurfaceProjectionResult {
  Vec3 foot = Vec3::Zero();
  double u = 0, v = 0;
  double distance = 0;
  SurfaceProjectionStatus status = SurfaceProjectionStatus::converged;
};

struct SurfaceInversion {
  bool on_surface = false;  // true when the closest point lies within the tolerance
  double u = 0, v = 0;
  double distance = std::numeric_limits<double>::infinity();
};

// A whole NURBS surface prepared for projection: decomposed into Bézier patches (each interior
// knot at full multiplicity, seed 000 §3.3), each with its cached coefficients. Immutable; all
// queries are const and thread-safe (one SurfaceScratch per thread).
// It projects onto the UNTRIMMED surface (trim_loops are ignored); trimmed faces go through
// PreparedModel + Projector (projection.hpp).
class SurfaceProjector {
 public:
  // Throws std::invalid_argument naming the field if surface.validate() fails.
  explicit SurfaceProjector(const NurbsSurface& surface);

  const std::vector<PreparedPatch>& patches() const { return patches_; }
  const Aabb& box() const { return box_; }

  // Exact closest point. Patches are visited in order of their bounding-box lower bound; a patch
  // whose bound is not below the best squared distance so far is skipped.
  SurfaceHit project(const Vec3& p, SurfaceStrategy strategy, SurfaceScratch& scratch,
                     SurfaceProjectionStats* stats = nullptr) const;
  // Warm start: the hint (u, v), e.g. the previous ICP foot point, gives an upper bound at once.
  // The answer is the same exact closest point (the hint only prunes).
  SurfaceHit project(const Vec3& p, double u_hint, double v_hint, SurfaceStrategy strategy,
                     SurfaceScratch& scratch, SurfaceProjectionStats* stats = nullptr) const;
  // Batch: results[i] for points[i], in parallel (TBB) unless `execution` is serial; identical
  // results for any
  // thread count (each point is independent). results.size() must equal points.size(). Points
  // with a NaN or infinite coordinate get status skipped_nonfinite. Allocates per-thread scratch
  // once.
  void project(std::span<const Vec3> points, SurfaceStrategy strategy,
               std::span<SurfaceProjectionResult> results,
               Execution execution = Execution::parallel,
               SurfaceProjectionStats* stats = nullptr) const;
  // Point inversion: the parameters of p if p lies on the surface within `tolerance` (distance).
  // Patches farther than the tolerance are pruned at once (seed 000 §11, convex hull property).
  SurfaceInversion invert(const Vec3& p, double tolerance, SurfaceScratch& scratch) const;
  // The same with a scratch of its own (allocates it: for occasional calls, not hot loops).
  SurfaceInversion invert(const Vec3& p, double tolerance) const;

 private:
  SurfaceHit run(const Vec3& p, SurfaceHit best, SurfaceStrategy strategy, SurfaceScratch& scratch,
                 SurfaceProjectionStats* stats) const;
  void ma_hewitt_boundaries(const Vec3& p, SurfaceHit& best, SurfaceProjectionStats* stats) const;

  NurbsSurface surface_;
  std::vector<PreparedPatch> patches_;
  int spans_u_ = 0, spans_v_ = 0;
  bool closed_u_ = false, closed_v_ = false;
  Aabb box_;
};

}  // namespace nurbsreg::engine
