#include "nurbsreg/icp/model_finder.hpp"

#include "blocks.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>

namespace nurbsreg::icp {

ModelCorrespondenceFinder::ModelCorrespondenceFinder(const engine::PreparedModel& model)
    : projector_(model),
      share_cap_(certificate_radius_for(model, 0)),
      width_cap_(patch_width_cap(model)) {
  certificate_radius_ = share_cap_;
  atlas_.reset(cell_side(), kAtlasHintsPerCell);
  use_spatial_order_ = model.patch_count() >= kSpatialOrderMinPatches;
}

// Atlas cells of half the radius cap: any point of a cell is within 0.87 cap of an anchor in the
// same cell, inside most certificates' radius, and a 10% subsample of a scan leaves one to three
// anchors per cell (quarter-cap cells left most of them empty: CertificateAtlas::find).
double ModelCorrespondenceFinder::cell_side() const {
  return certificate_radius_ > 0.0 ? 0.5 * certificate_radius_ : 1.0;
}

void ModelCorrespondenceFinder::reset(std::size_t scan_size) {
  scan_size_ = scan_size;
  has_previous_ = false;
  previous_position_.assign(scan_size, kNoPosition);
  borrow_failed_.assign(scan_size, 0);
  // certificate_radius_for(model, scan_size) from the caps computed once.
  const double cap = certificate_radius_for(scan_size, share_cap_, width_cap_);
  // A new cap changes the atlas' cells: kept certificates are dropped then too.
  if (!keep_certificates_ || cap != certificate_radius_) {
    certificate_radius_ = cap;
    atlas_.reset(cell_side(), kAtlasHintsPerCell);
  }
}

bool ModelCorrespondenceFinder::repeats_previous_query(const CorrespondenceQuery& query) const {
  const std::span<const std::size_t> ids = query.scan_indices;
  const std::size_t n = query.points.size();
  if (!has_previous_ || previous_size_ != n) return false;
  if (previous_all_) {
    for (std::size_t k = 0; k < ids.size(); ++k)
      if (ids[k] != k) return false;
    return true;
  }
  return ids.size() == n && std::equal(ids.begin(), ids.end(), previous_indices_.begin());
}

// Point k's hint (engine::HintView): its previous answer, if it had one, or a certificate
// borrowed from the atlas when that one does not cover the point and no borrowed one failed it
// before.
struct ModelCorrespondenceFinder::HintSource {
  // Same query as before: the previous answers, read in place (the projector reads hint k
  // before it writes answer k).
  const engine::ProjectionResults* in_place = nullptr;
  // Otherwise: the copied previous answers, by previous position of scan point s.
  const engine::ProjectionHint* carried = nullptr;
  std::size_t carried_count = 0;
  const std::uint32_t* previous_position = nullptr;
  std::size_t scan_size = 0;
  std::span<const std::size_t> scan_indices;
  // The query index of the point stored at position k (null: k itself).
  const std::uint32_t* order = nullptr;
  // Per point, the atlas's certificate to use instead (null: its own hint), looked up before
  // the projection: in a loop of their own the lookups' cache misses overlap, inside the
  // projection's they would wait one after another (measured: 40-60 ms more per 1 M points).
  const engine::ProjectionHint* const* borrowed = nullptr;
  std::size_t count = 0;  // query points

  engine::ProjectionHint own(std::size_t k) const {
    if (in_place != nullptr) return in_place->hint(k);
    if (carried != nullptr) {
      const std::size_t q = order == nullptr ? k : order[k];
      const std::size_t s = scan_indices.empty() ? q : scan_indices[q];
      // kNoPosition is beyond every count; the bound also keeps a stale position (a find()
      // that threw between prepare_hints and remember_query) from reading outside `carried`.
      if (s < scan_size && previous_position[s] < carried_count) {
        return carried[previous_position[s]];
      }
    }
    return {};
  }
  static engine::ProjectionHint at(const void* data, std::size_t k) {
    const auto& source = *static_cast<const HintSource*>(data);
    if (source.borrowed != nullptr) {
      // The projector asks in index order within its blocks: fetch a later point's borrowed
      // hint (random in the atlas) while this one is projected.
      constexpr std::size_t kAhead = 8;
      if (k + kAhead < source.count && source.borrowed[k + kAhead] != nullptr) {
        const auto* ahead = reinterpret_cast<const char*>(source.borrowed[k + kAhead]);
        __builtin_prefetch(ahead);
        __builtin_prefetch(ahead + sizeof(engine::ProjectionHint) - 1);
      }
      if (source.borrowed[k] != nullptr) return *source.borrowed[k];
    }
    return source.own(k);
  }
};

ModelCorrespondenceFinder::HintSource ModelCorrespondenceFinder::prepare_hints(
    const CorrespondenceQuery& query, bool repeats) {
  HintSource source;
  if (repeats) {
    source.in_place = &results_;
  } else if (has_previous_) {
    // The projection overwrites results_, so the previous answers move out first.
    carried_.resize(previous_size_);
    detail::for_each_block(previous_size_, query.parallel,
                           [&](std::size_t begin, std::size_t end, std::size_t) {
                             for (std::size_t j = begin; j < end; ++j)
                               carried_[j] = results_.hint(j);
                           });
    // By stored position j of the previous query (its order still holds here).
    for (std::size_t j = 0; j < previous_size_; ++j)
      previous_position_[previous_index(query_index(j))] = static_cast<std::uint32_t>(j);
    source.carried = carried_.data();
    source.carried_count = previous_size_;
    source.previous_position = previous_position_.data();
    source.scan_size = previous_position_.size();
    source.scan_indices = query.scan_indices;
  }
  if (!repeats) choose_order(query);
  gather_points(query);
  if (ordered_) source.order = order_.data();
  if (atlas_.size() > 0) {
    const std::span<const engine::Vec3> points = stored_points(query);
    const std::size_t n = points.size();
    borrowed_.resize(n);
    const std::span<const std::size_t> ids = query.scan_indices;
    // Which points keep their own hint, in stored order (the previous answers and the points are
    // read in sequence: in the cell order each read was a cache miss).
    needs_lookup_.resize(n);
    detail::for_each_block(n, query.parallel, [&](std::size_t begin, std::size_t end, std::size_t) {
      for (std::size_t k = begin; k < end; ++k) {
        const std::size_t q = query_index(k);
        needs_lookup_[k] = !stopped_borrowing(ids.empty() ? q : ids[q]) &&
                           !source.own(k).certificate.covers(points[k]);
        borrowed_[k] = nullptr;
      }
    });
    // The others in an order that keeps each atlas cell's points together (the lookups' probes
    // then hit the cache); each point's lookup is its own, so the order changes no result.
    atlas_.lookup_order(points, needs_lookup_, query.parallel, lookup_order_);
    const std::size_t lookups = lookup_order_.index.size();
    detail::for_each_block(
        lookups, query.parallel, [&](std::size_t begin, std::size_t end, std::size_t) {
          // A cell's points come one after another: they share its neighbourhood.
          CertificateAtlas::Neighbourhood near;
          for (std::size_t i = begin; i < end; ++i) {
            borrowed_[lookup_order_.index[i]] = atlas_.find(lookup_order_.points[i], near);
          }
        });
    source.borrowed = borrowed_.data();
    source.count = n;
  }
  return source;
}

void ModelCorrespondenceFinder::remember_query(const CorrespondenceQuery& query, bool repeats) {
  if (repeats) return;
  if (has_previous_) {
    for (std::size_t j = 0; j < previous_size_; ++j)
      previous_position_[previous_index(j)] = kNoPosition;
  }
  const std::span<const std::size_t> ids = query.scan_indices;
  bool all = true;
  for (std::size_t k = 0; all && k < ids.size(); ++k)
    all = ids[k] == k;
  has_previous_ = true;
  previous_all_ = all;
  previous_size_ = query.points.size();
  std::size_t needed = all ? previous_size_ : 0;
  if (all) {
    previous_indices_.clear();
  } else {
    previous_indices_.assign(ids.begin(), ids.end());
    for (const std::size_t s : ids)
      needed = std::max(needed, s + 1);
  }
  // Scan indices should be below reset()'s scan_size; more is tolerated.
  if (previous_position_.size() < needed) previous_position_.resize(needed, kNoPosition);
  if (borrow_failed_.size() < needed) borrow_failed_.resize(needed, 0);
}

// A borrowed certificate proved point k when the projection kept it as the answer's certificate
// (ProjectionResults::certificate: the hint's when it held; a failed one leaves none, or a new
// one anchored at the point itself when certifying). Flags are only ever set, so a scan point
// named twice in a query ends the same whichever copy is marked last; the two copies may be
// marked from two threads, hence the atomic (relaxed: a plain byte store) writes.
void ModelCorrespondenceFinder::remember_failed_borrows(const CorrespondenceQuery& query) {
  if (results_.certificate.empty()) return;
  const std::span<const std::size_t> ids = query.scan_indices;
  const auto mark = [&](std::size_t begin, std::size_t end, std::size_t) {
    for (std::size_t k = begin; k < end; ++k) {
      const engine::ProjectionHint* borrowed = borrowed_[k];
      if (borrowed == nullptr) continue;
      const engine::WarmCertificate& kept = results_.certificate[k];
      const bool proven = results_.status[k] == engine::ProjectionStatus::ok &&
                          kept.radius > 0.0f && kept.anchor == borrowed->certificate.anchor;
      if (!proven) {
        const std::size_t q = query_index(k);
        std::atomic_ref<std::uint8_t>(borrow_failed_[ids.empty() ? q : ids[q]])
            .store(1, std::memory_order_relaxed);
      }
    }
  };
  detail::for_each_block(query.points.size(), query.parallel, mark);
}

// The point lies beyond an open edge of the model when its foot is on a face boundary (a trim
// edge, as the engine reports, or the surface's domain boundary) and the offset is not along the
// normal (an interior-type foot, e.g. on a closed seam, has p - foot parallel to the normal).
bool ModelCorrespondenceFinder::beyond_edge(std::size_t k, const engine::Vec3& p,
                                            const Correspondence& c) const {
  const int entity = results_.entity[k];
  const double distance = results_.distance[k];
  if (entity < 0 || !(distance > 0.0)) return false;
  const auto off_normal = [&] {
    return std::abs((p - c.foot).dot(c.normal)) < (1.0 - 1e-6) * distance;
  };
  if (results_.on_trim_edge[k]) return off_normal();
  const engine::PreparedModel::SurfaceDomain& domain = projector_.model().surface_domain(entity);
  const engine::ParamInterval du = domain.u;
  const engine::ParamInterval dv = domain.v;
  const double u = results_.u[k];
  const double v = results_.v[k];
  const double eps = 1e-12;
  const bool on_edge = u <= du.lo + eps * du.width() || u >= du.hi - eps * du.width() ||
                       v <= dv.lo + eps * dv.width() || v >= dv.hi - eps * dv.width();
  return on_edge && off_normal();
}

void ModelCorrespondenceFinder::choose_order(const CorrespondenceQuery& query) {
  const std::size_t n = query.points.size();
  // spatial_order runs TBB loops of its own: not for a serial query.
  ordered_ = use_spatial_order_ && query.parallel && n >= kSpatialOrderMin &&
             n <= std::numeric_limits<std::uint32_t>::max();
  if (ordered_) engine::spatial_order(engine::PointView::of(query.points), order_, order_scratch_);
}

void ModelCorrespondenceFinder::gather_points(const CorrespondenceQuery& query) {
  if (!ordered_) return;
  const std::size_t n = query.points.size();
  ordered_points_.resize(n);
  detail::for_each_block(n, query.parallel, [&](std::size_t begin, std::size_t end, std::size_t) {
    for (std::size_t p = begin; p < end; ++p)
      ordered_points_[p] = query.points[order_[p]];
  });
}

std::span<const engine::Vec3> ModelCorrespondenceFinder::stored_points(
    const CorrespondenceQuery& query) const {
  if (!ordered_) return query.points;
  return {ordered_points_.data(), ordered_points_.size()};
}

// New certificates (made only when certifying; anchored at this query's point) join the atlas
// in query order: the atlas is not thread-safe, and between equal clearances the order decides
// which one a cell keeps, so the atlas is the same whichever order the answers are stored in.
void ModelCorrespondenceFinder::insert_made_certificates(std::span<const engine::Vec3> points) {
  made_.clear();
  for (std::size_t p = 0; p < points.size(); ++p) {
    if (results_.status[p] != engine::ProjectionStatus::ok) continue;
    const engine::WarmCertificate& c = results_.certificate[p];
    if (c.radius > 0.0f && c.anchor == points[p].cast<float>()) {
      made_.emplace_back(static_cast<std::uint32_t>(query_index(p)), static_cast<std::uint32_t>(p));
    }
  }
  if (ordered_) std::sort(made_.begin(), made_.end());
  for (const auto& [query_point, p] : made_)
    atlas_.insert(results_.hint(p));
}

const engine::ProjectionResults& ModelCorrespondenceFinder::last_results() const {
  if (!ordered_) return results_;
  if (!query_order_current_) {
    query_order_results_.resize(results_.size(), !results_.foot.empty(), false);
    query_order_results_.scatter_from(results_, order_);
    query_order_current_ = true;
  }
  return query_order_results_;
}

void ModelCorrespondenceFinder::find(const CorrespondenceQuery& query,
                                     std::span<Correspondence> out) {
  try {
    answer(query, out);
  } catch (...) {
    // A query cut short (a cancelled loop: engine::Cancelled) leaves the order, the answers and
    // the positions of the previous query out of step: the next query starts afresh, as after
    // reset(), instead of reading one through the other.
    has_previous_ = false;
    ordered_ = false;
    results_.resize(0);
    std::fill(previous_position_.begin(), previous_position_.end(), kNoPosition);
    throw;
  }
}

void ModelCorrespondenceFinder::answer(const CorrespondenceQuery& query,
                                       std::span<Correspondence> out) {
  const std::size_t n = query.points.size();
  const auto t0 = std::chrono::steady_clock::now();
  // Certificates are made on the coarse stages' subsamples once the solver expects small moves:
  // the full-resolution stage then borrows them for the points between (they prove about 95% of
  // its first pass). Making one costs about two cold projections, so at full resolution, where
  // ICP usually ends after one more pass, they are used, and made only as below.
  const bool subsample = !query.scan_indices.empty() && query.scan_indices.size() < scan_size_;
  const bool certify_for_atlas = subsample && query.expected_motion < 0.5 * certificate_radius_;
  // At full resolution, the points no certificate proved (a borrowed one's clearance too short
  // for them, none near) are searched again by every later pass: when several passes are still
  // to come, each gets one of its own, of a radius for the next pass's motion only, kept as its
  // own hint (not lent: the atlas is for the points of new queries). Not on models whose patches
  // are narrow against the atlas's share of the diagonal (the cap came from their widths, the
  // IEA blade's 5 cm strips): there a point's proof needs a box over many patches, and making
  // one cost about eight of the cold searches it saves (bench/README.md).
  const double own_radius = kOwnCertificateMotions * query.expected_motion;
  const bool certify_own = !subsample && !certify_for_atlas && width_cap_ >= share_cap_ &&
                           query.later_queries >= kOwnCertificateLaterQueries && own_radius > 0.0 &&
                           own_radius < certificate_radius_;
  const bool certify = certify_for_atlas || certify_own;
  // Otherwise, at full resolution, the points no certificate proved get clearance certificates
  // (engine::WarmCertificate::clearance_only) for the next pass's motion: the search that
  // answers them also bounds the rest of the model beyond their foot's patch, at about its own
  // cost, and the next pass clips that one patch instead of searching again. Made on every such
  // pass: the first on all points and the last (then unused) cannot tell whether one follows.
  // Not on models whose patches are narrow against the share cap (the IEA blade's strips): a
  // neighbouring strip lies within the margin of most of its points, and the walks cost more
  // than the few certificates made save (bench/README.md).
  const double clearance_radius = kClearanceMotions * query.expected_motion;
  const bool certify_clearance = !subsample && !certify && n >= kClearanceMinPoints &&
                                 width_cap_ >= share_cap_ && clearance_radius > 0.0 &&
                                 clearance_radius < certificate_radius_;
  const bool repeats = repeats_previous_query(query);
  query_order_current_ = false;
  const HintSource source = prepare_hints(query, repeats);
  const std::span<const engine::Vec3> points = stored_points(query);
  const auto t1 = std::chrono::steady_clock::now();
  const engine::HintView hints(&source, n, &HintSource::at);
  engine::ProjectionOptions options;
  options.max_distance = query.max_distance;
  options.certify = certify;
  options.certify_clearance = certify_clearance;
  options.certificate_radius = certify_own         ? own_radius
                               : certify_clearance ? clearance_radius
                                                   : certificate_radius_;
  options.certificate_span = certificate_span_for(scan_size_);
  // Feet and normals straight into the answers (no copy, 48 bytes a point less in results_); in
  // spatial order into answers in that order first, so that each answer goes to its place in
  // query order once, whole, below (written there twice, each a cache miss, it cost more).
  if (ordered_) ordered_answers_.resize(n);
  Correspondence* const answers = ordered_ ? ordered_answers_.data() : out.data();
  options.foot_sink = {
      answers, [](void* data, std::size_t k, const engine::Vec3& foot, const engine::Vec3& normal) {
        Correspondence& c = static_cast<Correspondence*>(data)[k];
        c.foot = foot;
        c.normal = normal;
      }};
  const auto view = engine::PointView::of(points);
  if (query.parallel) {
    projector_.project(view, options, results_, hints, &counters_);
  } else {
    projector_.project_serial(view, options, results_, hints, &counters_);
  }
  const auto t2 = std::chrono::steady_clock::now();
  remember_query(query, repeats);
  if (source.borrowed != nullptr) remember_failed_borrows(query);
  detail::for_each_block(n, query.parallel, [&](std::size_t begin, std::size_t end, std::size_t) {
    for (std::size_t k = begin; k < end; ++k) {
      Correspondence& c = answers[k];
      c.valid = results_.status[k] == engine::ProjectionStatus::ok;
      if (c.valid) {
        c.distance = results_.distance[k];
        c.on_boundary = beyond_edge(k, points[k], c);
      }
      if (ordered_) out[order_[k]] = c;
    }
  });
  if (certify_for_atlas) insert_made_certificates(points);
  // Where a pass's time goes (`-v`): the hints (atlas lookups), the projection and its proofs.
  const auto ms = [](auto a, auto b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
  };
  spdlog::debug(
      "find {} points ({}{}): hints {:.1f} ms, projection {:.1f} ms, rest {:.1f} ms; certified {}, "
      "reach {}, made {}, patches {}, newton {}, atlas {}",
      n, repeats ? "repeat" : "new query", certify ? ", certify" : "", ms(t0, t1), ms(t1, t2),
      ms(t2, std::chrono::steady_clock::now()), counters_.certified, counters_.reach_proven,
      counters_.certificates_made, counters_.patches_visited, counters_.newton_iterations,
      atlas_.size());
}

}  // namespace nurbsreg::icp
