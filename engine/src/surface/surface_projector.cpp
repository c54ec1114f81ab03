// Whole-surface projection: patch ordering, warm start, batches and point inversion.

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "nurbsreg/engine/cancellation.hpp"
#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/surface_projection.hpp"

namespace nurbsreg::engine {
namespace {

// Does the surface close on itself across `u` (or `v`) = domain ends? Sampled: the two boundary
// curves coincide at 17 points (seed 000 §8, Fig. 13).
bool closed_in(const NurbsSurface& s, bool in_u, double tolerance) {
  const ParamInterval a = in_u ? s.domain_u() : s.domain_v();
  const ParamInterval b = in_u ? s.domain_v() : s.domain_u();
  for (int k = 0; k <= 16; ++k) {
    const double x = b.to_parent(k / 16.0);
    const Vec3 p = in_u ? s.evaluate(a.lo, x) : s.evaluate(x, a.lo);
    const Vec3 q = in_u ? s.evaluate(a.hi, x) : s.evaluate(x, a.hi);
    if ((p - q).norm() > tolerance) return false;
  }
  return true;
}

}  // namespace

SurfaceProjector::SurfaceProjector(const NurbsSurface& surface) : surface_(surface) {
  if (auto error = surface.validate()) {
    throw std::invalid_argument("surface \"" + surface.name + "\": " + *error);
  }
  const std::vector<BezierPatch> bezier = decompose(surface, &spans_u_, &spans_v_);
  patches_.reserve(bezier.size());
  for (const BezierPatch& b : bezier) {
    patches_.push_back(prepare_patch(b));
    box_.extend(patches_.back().box);
  }
  const double tolerance = 1e-12 * std::max(box_.diagonal(), 1e-300);
  closed_u_ = closed_in(surface, true, tolerance);
  closed_v_ = closed_in(surface, false, tolerance);
}

SurfaceHit SurfaceProjector::run(const Vec3& p, SurfaceHit best, SurfaceStrategy strategy,
                                 SurfaceScratch& scratch, SurfaceProjectionStats* stats) const {
  if (!p.allFinite()) return best;  // no closest point: distance_sq stays as given (inf)
  if (strategy == SurfaceStrategy::ma_hewitt) ma_hewitt_boundaries(p, best, stats);
  auto& order = scratch.order;
  order.clear();
  for (int k = 0; k < static_cast<int>(patches_.size()); ++k) {
    const PreparedPatch& pp = patches_[k];
    const double to_sphere = std::max(0.0, (p - pp.sphere.center).norm() - pp.sphere.radius);
    order.emplace_back(std::max(pp.box.squared_distance(p), to_sphere * to_sphere), k);
  }
  // Nearest bound first; ties by index, so the visiting order (and the answer) is deterministic.
  std::sort(order.begin(), order.end());
  for (const auto& [lower, k] : order) {
    // Both bounds are exact lower bounds of the patch's distance (convex hull property).
    if (lower > best.distance_sq) break;
    if (strategy == SurfaceStrategy::spherical_clipping) {
      project_onto_patch(patches_[k], p, best, scratch, stats);
    } else {
      project_onto_patch_ma_hewitt(patches_[k], p, best, stats);
    }
  }
  return best;
}

SurfaceHit SurfaceProjector::project(const Vec3& p, SurfaceStrategy strategy,
                                     SurfaceScratch& scratch, SurfaceProjectionStats* stats) const {
  return run(p, SurfaceHit{}, strategy, scratch, stats);
}

SurfaceHit SurfaceProjector::project(const Vec3& p, double u_hint, double v_hint,
                                     SurfaceStrategy strategy, SurfaceScratch& scratch,
                                     SurfaceProjectionStats* stats) const {
  // The patch holding the hint: patches are laid out [a * spans_v + b] in parameter order.
  const ParamInterval du = surface_.domain_u(), dv = surface_.domain_v();
  const double u = std::clamp(u_hint, du.lo, du.hi), v = std::clamp(v_hint, dv.lo, dv.hi);
  int a = 0, b = 0;
  while (a + 1 < spans_u_ && patches_[(a + 1) * spans_v_].patch.param_u.lo <= u)
    ++a;
  while (b + 1 < spans_v_ && patches_[b + 1].patch.param_v.lo <= v)
    ++b;
  const PreparedPatch& pp = patches_[a * spans_v_ + b];
  // A local Newton from the hint makes the bound tight; the full search below keeps it exact.
  double s = pp.patch.param_u.to_local(u), t = pp.patch.param_v.to_local(v);
  SurfaceHit start;
  start.distance_sq = newton_on_patch(pp.patch, p, 0.0, 1.0, 0.0, 1.0, s, t, start.foot, stats);
  start.u = pp.patch.param_u.to_parent(s);
  start.v = pp.patch.param_v.to_parent(t);
  if (strategy == SurfaceStrategy::ma_hewitt) start = SurfaceHit{};  // its own candidates only
  return run(p, start, strategy, scratch, stats);
}

void SurfaceProjector::project(std::span<const Vec3> points, SurfaceStrategy strategy,
                               std::span<SurfaceProjectionResult> results, Execution execution,
                               SurfaceProjectionStats* stats) const {
  if (points.size() != results.size()) {
    throw std::invalid_argument("SurfaceProjector::project: results.size() != points.size()");
  }
  struct Local {
    SurfaceScratch scratch;
    SurfaceProjectionStats stats;
  };
  tbb::enumerable_thread_specific<Local> locals;
  auto body = [&](const tbb::blocked_range<std::size_t>& range) {
    Local& local = locals.local();
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      SurfaceProjectionResult& out = results[i];
      if (!points[i].allFinite()) {
        out = SurfaceProjectionResult{};
        out.status = SurfaceProjectionStatus::skipped_nonfinite;
        continue;
      }
      const SurfaceHit hit = project(points[i], strategy, local.scratch, &local.stats);
      out.foot = hit.foot;
      out.u = hit.u;
      out.v = hit.v;
      out.distance = std::sqrt(hit.distance_sq);
      out.status = std::isfinite(hit.distance_sq) ? SurfaceProjectionStatus::converged
                                                  : SurfaceProjectionStatus::no_candidate;
    }
  };
  const tbb::blocked_range<std::size_t> all(0, points.size(), 64);
  if (execution == Execution::parallel) {
    tbb::parallel_for(all, body);
    nurbsreg::engine::stop_if_cancelled();
  } else {
    body(all);
  }
  if (stats) {
    // Integer sums: the same totals in any combination order.
    for (const Local& local : locals)
      stats->add(local.stats);
  }
}

SurfaceInversion SurfaceProjector::invert(const Vec3& p, double tolerance,
                                          SurfaceScratch& scratch) const {
  // Seed 000 §11: only patches whose hull is within the tolerance can hold p; starting the
  // clipping sphere at the tolerance prunes all others at once.
  SurfaceHit start;
  start.distance_sq = tolerance * tolerance;
  const SurfaceHit hit = run(p, start, SurfaceStrategy::spherical_clipping, scratch, nullptr);
  SurfaceInversion result;
  if (hit.distance_sq < start.distance_sq) {
    result.on_surface = true;
    result.u = hit.u;
    result.v = hit.v;
    result.distance = std::sqrt(hit.distance_sq);
  }
  return result;
}

SurfaceInversion SurfaceProjector::invert(const Vec3& p, double tolerance) const {
  SurfaceScratch scratch;
  return invert(p, tolerance, scratch);
}

}  // namespace nurbsreg::engine
