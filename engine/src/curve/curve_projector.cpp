// Whole-curve projection: Bézier pieces under a bounding-box tree, nearest-first traversal with
// circular clipping on the leaves (seed paper 002), or Ma & Hewitt over every piece (seed 000).
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "curve/curve_local_solve.hpp"
#include "nurbsreg/engine/cancellation.hpp"
#include "nurbsreg/engine/curve_projection.hpp"
#include "nurbsreg/engine/decompose.hpp"
#include "reference/curve_ma_hewitt.hpp"

namespace nurbsreg::engine {
namespace {

// Deeper than any balanced tree over a std::vector of pieces can be.
constexpr int kMaxTreeStack = 128;

}  // namespace

CurveProjector::CurveProjector(const NurbsCurve& curve) {
  if (auto error = curve.validate()) {
    throw std::invalid_argument("curve \"" + curve.name + "\": " + *error);
  }
  domain_ = curve.domain();
  const std::vector<BezierCurve> pieces = decompose(curve);
  pieces_.reserve(pieces.size());
  for (const BezierCurve& piece : pieces)
    pieces_.push_back(prepare_curve_piece(piece));
  nodes_.reserve(2 * pieces_.size());
  root_ = build(0, static_cast<int>(pieces_.size()));
}

int CurveProjector::build(int first, int last) {
  const int index = static_cast<int>(nodes_.size());
  nodes_.push_back({});
  Node node;
  node.first = first;
  node.last = last;
  for (int i = first; i < last; ++i)
    node.box.extend(pieces_[i].box);
  if (last - first > 1) {
    // Pieces are in parameter order, so halving the index range keeps neighbours together.
    const int mid = first + (last - first) / 2;
    node.left = build(first, mid);
    node.right = build(mid, last);
  }
  nodes_[index] = node;
  return index;
}

int CurveProjector::piece_index(double u) const {
  const auto it = std::upper_bound(
      pieces_.begin(), pieces_.end(), u,
      [](double x, const PreparedCurvePiece& pc) { return x < pc.piece.param.lo; });
  return it == pieces_.begin() ? 0 : static_cast<int>(std::prev(it) - pieces_.begin());
}

Vec3 CurveProjector::evaluate(double u) const {
  u = std::clamp(u, domain_.lo, domain_.hi);
  const PreparedCurvePiece& pc = pieces_[piece_index(u)];
  Vec3 c;
  pc.evaluate_local(std::clamp(pc.piece.param.to_local(u), 0.0, 1.0), 0, &c);
  return pc.origin + c;
}

CurveHit CurveProjector::run(const Vec3& p, const CurveHit& seed, CurveStrategy strategy,
                             CurveProjectionStats& stats) const {
  ++stats.queries;
  if (strategy == CurveStrategy::ma_hewitt) {
    // Seed 000 §6: candidates from every piece, the nearest one polished by Newton-Raphson.
    detail::MaHewittCandidate chosen;
    int chosen_piece = -1;
    for (int i = 0; i < static_cast<int>(pieces_.size()); ++i) {
      detail::MaHewittCandidate candidate;
      detail::ma_hewitt_candidates(pieces_[i], p - pieces_[i].origin, candidate, stats);
      if (candidate.found && candidate.d2 < chosen.d2) {
        chosen = candidate;
        chosen_piece = i;
      }
    }
    CurveHit best;
    if (chosen_piece < 0) return best;
    const PreparedCurvePiece& pc = pieces_[chosen_piece];
    const Vec3 q = p - pc.origin;
    const detail::LocalMinimum r =
        detail::ma_hewitt_newton(pc, q, chosen.t, stats.newton_iterations);
    Vec3 c;
    pc.evaluate_local(chosen.t, 0, &c);
    if (!detail::offer(pc, r.t, r.d2, r.point, best) || r.d2 > chosen.d2) {
      best = {};
      detail::offer(pc, chosen.t, chosen.d2, c, best);
    }
    return best;
  }

  // Circular clipping: depth-first over the box tree, nearer child first, so the first leaves
  // reached give a small elimination radius and most of the tree is pruned by its boxes.
  CurveHit best = seed;
  int stack[kMaxTreeStack];
  int top = 0;
  stack[top++] = root_;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    // Relative margin: never prune a box on rounding of its distance.
    if (node.box.squared_distance(p) * (1.0 - 1e-12) > best.distance_sq) {
      stats.pieces_pruned += static_cast<std::uint64_t>(node.last - node.first);
      continue;
    }
    if (node.left < 0) {
      project_onto_piece(pieces_[node.first], p, best, &stats);
      continue;
    }
    const double dl = nodes_[node.left].box.squared_distance(p);
    const double dr = nodes_[node.right].box.squared_distance(p);
    const bool left_first = dl <= dr;
    stack[top++] = left_first ? node.right : node.left;
    stack[top++] = left_first ? node.left : node.right;
  }
  return best;
}

CurveHit CurveProjector::project(const Vec3& p, CurveStrategy strategy,
                                 CurveProjectionStats* stats) const {
  CurveProjectionStats local;
  const CurveHit hit = run(p, CurveHit{}, strategy, local);
  if (stats) *stats += local;
  return hit;
}

CurveHit CurveProjector::project(const Vec3& p, double hint_u, CurveStrategy strategy,
                                 CurveProjectionStats* stats) const {
  CurveHit seed;
  if (strategy == CurveStrategy::circular_clipping && std::isfinite(hint_u)) {
    seed.u = std::clamp(hint_u, domain_.lo, domain_.hi);
    seed.foot = evaluate(seed.u);
    seed.distance_sq = (seed.foot - p).squaredNorm();
  }
  CurveProjectionStats local;
  const CurveHit hit = run(p, seed, strategy, local);
  if (stats) *stats += local;
  return hit;
}

void CurveProjector::project(std::span<const Vec3> points, std::span<CurveProjectionResult> results,
                             CurveStrategy strategy, CurveProjectionStats* stats,
                             Execution execution) const {
  if (points.size() != results.size()) {
    throw std::invalid_argument("CurveProjector::project: " + std::to_string(points.size()) +
                                " points but " + std::to_string(results.size()) + " results");
  }
  const auto one = [&](std::size_t i, CurveProjectionStats& acc) {
    CurveProjectionResult& out = results[i];
    if (!points[i].allFinite()) {
      out = CurveProjectionResult{};
      out.status = CurveProjectionStatus::skipped_nonfinite;
      return;
    }
    CurveProjectionStats local;
    const CurveHit hit = run(points[i], CurveHit{}, strategy, local);
    out.foot = hit.foot;
    out.u = hit.u;
    out.distance = std::sqrt(hit.distance_sq);
    out.status = local.depth_limit_hits > 0 ? CurveProjectionStatus::depth_limited
                                            : CurveProjectionStatus::converged;
    acc += local;
  };
  if (execution == Execution::serial) {
    CurveProjectionStats acc;
    for (std::size_t i = 0; i < points.size(); ++i)
      one(i, acc);
    if (stats) *stats += acc;
    return;
  }
  tbb::enumerable_thread_specific<CurveProjectionStats> per_thread;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 256),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      CurveProjectionStats& acc = per_thread.local();
                      for (std::size_t i = range.begin(); i != range.end(); ++i)
                        one(i, acc);
                    });
  nurbsreg::engine::stop_if_cancelled();
  // Integer sums: the total does not depend on how the work was split.
  if (stats) {
    for (const CurveProjectionStats& s : per_thread)
      *stats += s;
  }
}

std::optional<double> CurveProjector::invert(const Vec3& p, double tolerance) const {
  if (!p.allFinite() || !(tolerance >= 0.0)) return std::nullopt;
  // Seed 000 §11: only pieces whose convex hull comes within the tolerance can hold p, so the
  // search starts with the tolerance as its elimination radius; everything farther is pruned.
  CurveHit seed;
  seed.distance_sq = std::nextafter(tolerance * tolerance, std::numeric_limits<double>::max());
  CurveProjectionStats stats;
  const CurveHit hit = run(p, seed, CurveStrategy::circular_clipping, stats);
  if (!(hit.distance_sq < seed.distance_sq)) return std::nullopt;
  return hit.u;
}

}  // namespace nurbsreg::engine
