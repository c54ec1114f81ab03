#pragma once
// Exact point projection and point inversion for NURBS curves.
//
// Two strategies:
//  - circular_clipping (default): seed paper 002 (Chen et al. 2008). The squared distance from
//    the point to a rational Bézier piece is a rational Bernstein function of degree 2n whose
//    coefficients come from per-piece constants W_k, G_k, E_k (DESIGN.md "Projection: curves");
//    sub-intervals whose coefficients all exceed the best squared distance so far are
//    eliminated (Property 1), unimodal ones (Property 2) go to a safeguarded Newton iteration on
//    the curve itself (Ye 1994 hybrid of bisection and Newton), the rest are halved. The result
//    is the global minimum up to rounding.
//  - ma_hewitt: seed paper 000 (Ma & Hewitt 2003), Algorithms 1, 3 and 5 (valid control
//    polygon, Theorem 1 end-point test, candidate extraction on flat sub-curves) followed by
//    Newton-Raphson. Kept for comparison. NOT exact: its Theorem 1 fails in 3-D (Chen et al.
//    2007 counterexample), and "flat enough" candidates chosen before Newton can pick the wrong
//    branch; the tests show a 3-D and a planar case. (Seed 002 reports wrong answers on its
//    Fig. 5; this implementation happens to be right on those points.)
//
// Preparation (prepare_curve_piece, CurveProjector's constructor) allocates; every query is
// const, allocation-free and thread-safe. Results are in the PARENT curve's parameter u.

#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <vector>

#include "nurbsreg/engine/bezier.hpp"
#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/nurbs_curve.hpp"

namespace nurbsreg::engine {

enum class CurveStrategy : std::uint8_t { circular_clipping, ma_hewitt };

// The best point found so far: `u` in the parent curve's parameter, `foot` = C(u).
struct CurveHit {
  double u = 0.0;
  double distance_sq = std::numeric_limits<double>::infinity();
  Vec3 foot = Vec3::Zero();

  bool found() const { return distance_sq < std::numeric_limits<double>::infinity(); }
};

// Work counters; add up over queries (integers: the sum does not depend on thread order).
struct CurveProjectionStats {
  std::uint64_t queries = 0;
  std::uint64_t pieces_pruned = 0;   // rejected by a bounding volume before any clipping
  std::uint64_t pieces_clipped = 0;  // squared-distance function built and clipped
  std::uint64_t subdivisions = 0;    // midpoint splits (clipping) or sub-curve splits (MH)
  std::uint64_t eliminated = 0;      // sub-intervals dropped by Property 1 / Theorem 1
  std::uint64_t local_solves = 0;    // safeguarded Newton runs (clipping) / candidates (MH)
  std::uint64_t newton_iterations = 0;
  std::uint64_t depth_limit_hits = 0;  // the subdivision safety net triggered

  CurveProjectionStats& operator+=(const CurveProjectionStats& o);
};

// A rational Bézier piece prepared for projection: built once, read-only afterwards.
struct PreparedCurvePiece {
  BezierCurve piece;  // as given (parent-space control points, parent parameter interval)
  // Local frame: the bounding-sphere centre. G, E and the local control points are relative to
  // it, so that small distances far from the world origin do not cancel away.
  Vec3 origin = Vec3::Zero();
  double radius = 0.0;  // max |P_i - origin|: the sphere holds the piece (convex hull)
  Aabb box;
  int degree = 0;
  // Homogeneous control points relative to `origin`, (w (P - o), w), and their first and
  // second hodographs (for C, C', C'' at any t without recomputing differences per call).
  std::array<Vec4, kMaxDegree + 1> local{};
  std::array<Vec4, kMaxDegree> d1{};
  std::array<Vec4, kMaxDegree> d2{};
  // Squared-distance constants of degree 2n (DESIGN.md): with q = p - origin,
  //   W_k f_k = G_k - 2 q.E_k + |q|^2 W_k.
  std::array<double, 2 * kMaxDegree + 1> W{};
  std::array<double, 2 * kMaxDegree + 1> G{};
  std::array<Vec3, 2 * kMaxDegree + 1> E{};

  // C and its derivatives with respect to the LOCAL t in [0, 1], relative to `origin`;
  // order <= 2.
  void evaluate_local(double t, int order, Vec3* derivs) const;
};

PreparedCurvePiece prepare_curve_piece(const BezierCurve& piece);

// Circular clipping on one piece. Exact: if the piece holds a point whose squared distance to
// p is below best.distance_sq, replaces `best` by the closest point of the piece and returns
// true; otherwise leaves `best` alone and returns false ("below" up to rounding: a point better
// by less than ~1e-13 of the squared extent may be ignored). The piece's end points are always
// candidates. Allocation-free (about 25 KB of stack for the subdivision stack), const,
// thread-safe. `stats` may be null. A non-finite p finds nothing (best unchanged).
bool project_onto_piece(const PreparedCurvePiece& piece, const Vec3& p, CurveHit& best,
                        CurveProjectionStats* stats = nullptr);

// Ma & Hewitt (seed 000, Algorithms 1, 3, 5 + Newton-Raphson) on one piece, with the same
// contract as project_onto_piece EXCEPT exactness: it may miss the closest point.
bool project_onto_piece_ma_hewitt(const PreparedCurvePiece& piece, const Vec3& p, CurveHit& best,
                                  CurveProjectionStats* stats = nullptr);

enum class CurveProjectionStatus : std::uint8_t {
  converged,          // the closest point (global minimum up to rounding)
  depth_limited,      // as above, but the subdivision safety net triggered on the way
  skipped_nonfinite,  // the input point had a NaN or infinite coordinate; nothing computed
};

struct CurveProjectionResult {
  Vec3 foot = Vec3::Zero();
  double u = 0.0;
  double distance = 0.0;  // Euclidean, >= 0
  CurveProjectionStatus status = CurveProjectionStatus::skipped_nonfinite;
};

// The former name of Execution (types.hpp), kept for code written against it.
using CurveExecution = Execution;

// A NURBS curve prepared for projection: Bézier decomposition, one PreparedCurvePiece per
// non-empty knot span, and a balanced bounding-box tree over the pieces (in parameter order).
// Immutable after construction; all queries are const and thread-safe.
class CurveProjector {
 public:
  // Throws std::invalid_argument with NurbsCurve::validate()'s message for an invalid curve.
  explicit CurveProjector(const NurbsCurve& curve);

  // The closest point on the curve. Circular clipping walks the box tree nearest-first and
  // prunes subtrees whose box is farther than the best distance so far; the elimination
  // radius starts from the end points of the first (nearest) piece and shrinks with every
  // piece solved. Ma & Hewitt visits every piece (as in the paper).
  CurveHit project(const Vec3& p, CurveStrategy strategy = CurveStrategy::circular_clipping,
                   CurveProjectionStats* stats = nullptr) const;
  // Warm start: C(hint_u) gives the first elimination radius at once (e.g. the previous ICP
  // iteration's answer), so most pieces are pruned by their boxes. The answer stays exact:
  // the hint only bounds the distance. Circular clipping only; Ma & Hewitt ignores the hint.
  CurveHit project(const Vec3& p, double hint_u,
                   CurveStrategy strategy = CurveStrategy::circular_clipping,
                   CurveProjectionStats* stats = nullptr) const;
  // Batch: results[i] for points[i] (sizes must match), written by index, so results are the
  // same for any thread count and identical to single-point calls. Parallel over blocks with
  // TBB unless `execution` is serial (the thread count is the caller's: tbb::global_control
  // or a task_arena). Non-finite points get status skipped_nonfinite. Allocates only the
  // per-thread counters, once per call; `stats` receives their (order-independent) sum.
  void project(std::span<const Vec3> points, std::span<CurveProjectionResult> results,
               CurveStrategy strategy = CurveStrategy::circular_clipping,
               CurveProjectionStats* stats = nullptr,
               Execution execution = Execution::parallel) const;

  // Point inversion (seed 000 §11): the parameter u of p when p lies on the curve, i.e. when
  // its distance to the curve is <= tolerance (then C(u) is the closest point to p); nullopt
  // when p is farther than `tolerance` from the curve (or tolerance < 0, or p not finite). The
  // tolerance is the first elimination radius, so pieces farther away are never clipped. On a
  // self-intersection either parameter may be returned.
  std::optional<double> invert(const Vec3& p, double tolerance) const;

  ParamInterval domain() const { return domain_; }
  const std::vector<PreparedCurvePiece>& pieces() const { return pieces_; }
  // C(u) on the prepared pieces (u clamped to the domain).
  Vec3 evaluate(double u) const;

 private:
  struct Node {
    Aabb box;
    int first = 0;  // pieces [first, last)
    int last = 0;
    int left = -1;  // children (both -1 for a leaf with one piece)
    int right = -1;
  };
  int build(int first, int last);
  int piece_index(double u) const;
  CurveHit run(const Vec3& p, const CurveHit& seed, CurveStrategy strategy,
               CurveProjectionStats& stats) const;

  ParamInterval domain_;
  std::vector<PreparedCurvePiece> pieces_;
  std::vector<Node> nodes_;
  int root_ = -1;
};

}  // namespace nurbsreg::engine
