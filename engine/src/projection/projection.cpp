#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/cancellation.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "projection/projector_state.hpp"

namespace nurbsreg::engine {

void ProjectionResults::resize(std::size_t n, bool feet, bool certificates) {
  certificate.resize(certificates ? n : 0);
  foot.resize(feet ? n : 0);
  distance.resize(n);
  signed_distance.resize(n);
  entity.resize(n);
  u.resize(n);
  v.resize(n);
  normal.resize(feet ? n : 0);
  status.resize(n);
  on_trim_edge.resize(n);
}

void ProjectionResults::copy_from(const ProjectionResults& part, std::size_t offset) {
  auto put = [offset](auto& to, const auto& from) {
    // A field the frame does not fill (normals, certificates) is empty in both: no offset into
    // an empty vector's null data (undefined behaviour, which UBSan stops on).
    if (from.empty()) return;
    if (offset + from.size() > to.size()) {
      throw std::logic_error("ProjectionResults::copy_from: " + std::to_string(from.size()) +
                             " results at " + std::to_string(offset) + " into " +
                             std::to_string(to.size()));
    }
    std::copy(from.begin(), from.end(), to.begin() + static_cast<std::ptrdiff_t>(offset));
  };
  put(foot, part.foot);
  put(distance, part.distance);
  put(signed_distance, part.signed_distance);
  put(entity, part.entity);
  put(u, part.u);
  put(v, part.v);
  put(normal, part.normal);
  put(status, part.status);
  put(on_trim_edge, part.on_trim_edge);
  put(certificate, part.certificate);
}

namespace {
// ProjectionResults::scatter_from for either index type.
template <class Index>
void scatter_into(ProjectionResults& to, const ProjectionResults& part,
                  std::span<const Index> ids) {
  if (part.size() != ids.size()) {
    throw std::logic_error("ProjectionResults::scatter_from: " + std::to_string(part.size()) +
                           " results for " + std::to_string(ids.size()) + " entries");
  }
  for (const Index i : ids) {
    if (i >= to.size()) {
      throw std::logic_error("ProjectionResults::scatter_from: entry " + std::to_string(i) +
                             " of " + std::to_string(to.size()));
    }
  }
  auto put = [&ids](auto& into, const auto& from, bool clear_missing) {
    if (into.empty()) return;
    for (std::size_t k = 0; k < ids.size(); ++k) {
      if (!from.empty()) {
        into[ids[k]] = from[k];
      } else if (clear_missing) {
        into[ids[k]] = {};
      }
    }
  };
  put(to.foot, part.foot, false);
  put(to.distance, part.distance, false);
  put(to.signed_distance, part.signed_distance, false);
  put(to.entity, part.entity, false);
  put(to.u, part.u, false);
  put(to.v, part.v, false);
  put(to.normal, part.normal, false);
  put(to.status, part.status, false);
  put(to.on_trim_edge, part.on_trim_edge, false);
  put(to.certificate, part.certificate, true);
}
}  // namespace

void ProjectionResults::scatter_from(const ProjectionResults& part,
                                     std::span<const std::size_t> ids) {
  scatter_into(*this, part, ids);
}

void ProjectionResults::scatter_from(const ProjectionResults& part,
                                     std::span<const std::uint32_t> ids) {
  scatter_into(*this, part, ids);
}

Projector::Projector(const PreparedModel& model) : model_(model), impl_(std::make_unique<Impl>()) {}

Projector::~Projector() = default;

namespace {
// Checks the hints and sizes the results for a frame: feet and normals unless a FootSink takes
// them, certificates only when the frame can have some (it certifies, or hints carry them).
void prepare_results(PointView points, const ProjectionOptions& options, HintView hints,
                     ProjectionResults& out) {
  if (options.certificate_span < 1 || options.certificate_span > kMaxCertificateSpan) {
    throw std::invalid_argument("Projector: certificate_span must be 1 .. " +
                                std::to_string(kMaxCertificateSpan) + " (got " +
                                std::to_string(options.certificate_span) + ")");
  }
  if (!hints.empty() && hints.size() != points.size()) {
    throw std::invalid_argument("Projector: " + std::to_string(hints.size()) + " hints for " +
                                std::to_string(points.size()) + " points");
  }
  out.resize(points.size(), !options.foot_sink,
             options.certify || options.certify_clearance || !hints.empty());
}

}  // namespace

double chain_margin_for(PointView points, std::span<const std::uint32_t> order) {
  // The median of a sample of the steps.
  constexpr std::size_t kEvery = 61;
  std::vector<double> steps;
  steps.reserve(order.size() / kEvery + 1);
  for (std::size_t j = 0; j + 1 < order.size(); j += kEvery) {
    const double step = (points[order[j + 1]] - points[order[j]]).norm();
    if (std::isfinite(step)) steps.push_back(step);
  }
  if (steps.empty()) return 0.0;
  auto middle = steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2);
  std::nth_element(steps.begin(), middle, steps.end());
  constexpr double kChainSteps = 4.0;
  return kChainSteps * *middle;
}

void Projector::project(PointView points, const ProjectionOptions& options, ProjectionResults& out,
                        HintView hints, ProjectionCounters* counters) {
  prepare_results(points, options, hints, out);
  for (ThreadState& s : impl_->states) {
    s.counters = {};
    s.surface_stats = {};
    s.curve_stats = {};
  }
  // Below this many points the ordering's own pass is not worth it (and a frame that small
  // stays in cache anyway).
  constexpr std::size_t kLocalityOrderMin = 8192;
  std::span<const std::uint32_t> order;
  const bool ordered = options.locality_order && hints.empty() &&
                       points.size() >= kLocalityOrderMin &&
                       points.size() <= std::numeric_limits<std::uint32_t>::max();
  const bool may_chain = options.chain_cold && hints.empty() &&
                         options.target == ProjectionTarget::surfaces && !options.certify &&
                         !options.certify_clearance;
  // In the caller's order (already a fine spatial one), or in the frame's own fine order.
  const bool chained_as_given =
      may_chain && options.chain_in_index_order && options.chain_margin > 0.0;
  const bool chained = may_chain && (chained_as_given || ordered);
  if (ordered && !chained_as_given) {
    spatial_order(points, impl_->order, impl_->order_scratch, chained ? kMaxOrderBits : 0);
    order = impl_->order;
  }
  double chain_margin = 0.0;
  if (chained) {
    chain_margin =
        options.chain_margin > 0.0 ? options.chain_margin : chain_margin_for(points, order);
  }
  // The default certificate cap is a share of the model's trimmed size: computed once per model
  // (single-threaded, milliseconds), here rather than by the first task of the loop while the
  // others wait for it.
  if (!(options.certificate_radius > 0.0)) (void)model_.geometry_bounds();
  if (chained) {
    // Whole chains per task: each starts afresh at a multiple of kChainLength of the order, so
    // the answers do not depend on how the frame was cut into tasks.
    const std::size_t chains = (points.size() + kChainLength - 1) / kChainLength;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(
                          0, chains, std::max<std::size_t>(1, options.grain / kChainLength)),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                        ThreadState& state = impl_->states.local();
                        const std::size_t begin = range.begin() * kChainLength;
                        const std::size_t end = std::min(points.size(), range.end() * kChainLength);
                        state.chain.margin = chain_margin;
                        if (order.empty()) {
                          project_range(points, options, out, hints, {}, begin, end, state);
                        } else {
                          project_block(points, options, order.subspan(begin, end - begin), out,
                                        state);
                        }
                        state.chain.margin = 0.0;
                      });
  } else {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, points.size(), std::max<std::size_t>(1, options.grain)),
        [&](const tbb::blocked_range<std::size_t>& range) {
          ThreadState& state = impl_->states.local();
          if (order.empty()) {
            project_range(points, options, out, hints, {}, range.begin(), range.end(), state);
          } else {
            project_block(points, options, order.subspan(range.begin(), range.size()), out, state);
          }
        });
  }
  nurbsreg::engine::stop_if_cancelled();
  if (counters) {
    *counters = {};
    // Integer sums: the order of combination does not matter.
    for (const ThreadState& s : impl_->states) {
      counters->points += s.counters.points;
      counters->skipped += s.counters.skipped;
      counters->patches_visited += s.counters.patches_visited;
      counters->subdivisions += static_cast<std::uint64_t>(s.surface_stats.subdivisions) +
                                static_cast<std::uint64_t>(s.curve_stats.subdivisions);
      counters->newton_iterations += static_cast<std::uint64_t>(s.surface_stats.newton_iterations);
      counters->certified += s.counters.certified;
      counters->reach_proven += s.counters.reach_proven;
      counters->certificates_made += s.counters.certificates_made;
      counters->listed += s.counters.listed;
      counters->lists_made += s.counters.lists_made;
      counters->edge_pieces_visited += s.counters.edge_pieces_visited;
      counters->trimmed_patches_visited += s.counters.trimmed_patches_visited;
      counters->rational_patches_visited += s.counters.rational_patches_visited;
      counters->region_drops += static_cast<std::uint64_t>(s.surface_stats.region_drops);
      counters->region_rejections += static_cast<std::uint64_t>(s.surface_stats.region_rejections);
    }
  }
}

namespace {
// The caller's FootSink, told each point's own index instead of its place in a block.
struct BlockSink {
  FootSink sink;
  std::span<const std::uint32_t> ids;

  static void write(void* data, std::size_t k, const Vec3& foot, const Vec3& normal) {
    const auto* self = static_cast<const BlockSink*>(data);
    self->sink.write(self->sink.data, self->ids[k], foot, normal);
  }
};
}  // namespace

void Projector::project_block(PointView points, const ProjectionOptions& options,
                              std::span<const std::uint32_t> ids, ProjectionResults& out,
                              ThreadState& state) const {
  // Points of a frame in no spatial order sit far apart in memory even when the order brings
  // them together in space: projected in place, each one read its point and wrote a dozen
  // entries of its answer to cache lines of its own. Gathered and written back in one pass
  // each, those misses overlap, and the projection runs on contiguous memory.
  state.staged_points.resize(ids.size());
  for (std::size_t k = 0; k < ids.size(); ++k)
    state.staged_points[k] = points[ids[k]];
  BlockSink block_sink{options.foot_sink, ids};
  ProjectionOptions block_options = options;
  if (options.foot_sink) block_options.foot_sink = FootSink{&block_sink, &BlockSink::write};
  state.staged.resize(ids.size(), !options.foot_sink, !out.certificate.empty());
  project_range(PointView::of(state.staged_points), block_options, state.staged, {}, {}, 0,
                ids.size(), state);
  scatter_into(out, state.staged, ids);
}

void Projector::project_serial(PointView points, const ProjectionOptions& options,
                               ProjectionResults& out, HintView hints,
                               ProjectionCounters* counters) {
  prepare_results(points, options, hints, out);
  ThreadState& state = impl_->states.local();
  state.counters = {};
  state.surface_stats = {};
  state.curve_stats = {};
  project_range(points, options, out, hints, {}, 0, points.size(), state);
  if (counters) {
    *counters = state.counters;
    counters->subdivisions = static_cast<std::uint64_t>(state.surface_stats.subdivisions) +
                             static_cast<std::uint64_t>(state.curve_stats.subdivisions);
    counters->newton_iterations = static_cast<std::uint64_t>(state.surface_stats.newton_iterations);
    counters->region_drops = static_cast<std::uint64_t>(state.surface_stats.region_drops);
    counters->region_rejections = static_cast<std::uint64_t>(state.surface_stats.region_rejections);
  }
}

}  // namespace nurbsreg::engine
