#pragma once
// The closest-point step of ICP, behind a small batch interface.
//
// ICP only needs, for each scan point already moved into the model frame, its closest point
// ("foot") on the model, the unit surface normal there and the distance. Anything that can
// answer that batch question plugs into the solver: the analytic primitives in analytic.hpp
// (exact, for tests and demos) or the engine's exact NURBS projector (warm-started from the
// previous iteration's foot, keyed by scan index).

#include <cstddef>
#include <limits>
#include <span>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::icp {

// One answer, written by index into caller-owned storage.
struct Correspondence {
  engine::Vec3 foot = engine::Vec3::Zero();     // closest point on the model (model frame)
  engine::Vec3 normal = engine::Vec3::UnitZ();  // unit surface normal at the foot; sign free
  double distance = std::numeric_limits<double>::infinity();  // |point - foot| >= 0
  // The foot is on a free (open) boundary of the model and the point lies beyond it, so
  // point - foot is not along the normal. Such pairs pull the scan towards the model's edge
  // (Turk & Levoy 1994; Rusinkiewicz & Levoy 2001, section 5): the solver drops them when
  // IcpOptions::reject_boundary. Finders that cannot tell leave it false.
  bool on_boundary = false;
  // false: no foot within query.max_distance, or the finder could not answer for this point.
  // The solver ignores foot/normal/distance of invalid entries.
  bool valid = false;
};

struct CorrespondenceQuery {
  // Points in the model frame (scan points moved by the current pose estimate).
  std::span<const engine::Vec3> points;
  // scan_indices[k] is the index in the full scan of points[k]. It is stable across the
  // iterations of one alignment (also across coarse-to-fine stages), so a finder may keep
  // per-scan-point state such as a warm-start hint (patch, u, v) of the previous foot.
  std::span<const std::size_t> scan_indices;
  // Points farther than this from the model are rejected by the solver anyway: a finder may
  // mark them invalid without computing their exact foot (e.g. prune its hierarchy with it).
  // +infinity means "answer every point".
  double max_distance = std::numeric_limits<double>::infinity();
  // false: answer on the calling thread only (the solver's serial path).
  bool parallel = true;
  // How far the points are expected to move before the next query (the solver's estimate from
  // its last step; +infinity when unknown). A finder may use it to decide whether per-point work
  // that pays off only for nearby later queries (ModelCorrespondenceFinder's certificates) is
  // worth doing; answers never depend on it.
  double expected_motion = std::numeric_limits<double>::infinity();
  // How many more queries of the same points the solver expects after this one (its steps'
  // contraction towards its tolerance; 0 when unknown or when this one is likely the last). A
  // finder may do per-point work now that pays off only over several later queries.
  int later_queries = 0;
};

// Contract for implementations:
// - find() writes out[k] for every k < query.points.size() (out has exactly that size) and
//   nothing else; the answer for point k may depend only on points[k], scan_indices[k] and
//   the finder's per-scan-index state, never on scheduling, so results are identical for any
//   thread count and for query.parallel == false.
// - The solver calls reset(scan_size) once at the start of every alignment, then find() once
//   per iteration, from one thread. find() may run its own tbb parallel loops.
class CorrespondenceFinder {
 public:
  virtual ~CorrespondenceFinder() = default;

  // Forget per-point state (warm starts); scan indices will be < scan_size.
  virtual void reset(std::size_t scan_size) { (void)scan_size; }

  virtual void find(const CorrespondenceQuery& query, std::span<Correspondence> out) = 0;
};

}  // namespace nurbsreg::icp
