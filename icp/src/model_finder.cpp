#include "nurbsreg/icp/model_finder.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace nurbsreg::icp {

ModelCorrespondenceFinder::ModelCorrespondenceFinder(const engine::PreparedModel& model)
    : projector_(model), certificate_radius_(1e-2 * model.bounds().diagonal()) {
  atlas_.reset(cell_side());
}

// Atlas cells of a quarter of the radius cap: any point of a cell is within 0.43 cap of an
// anchor in the same cell, inside most certificates' radius.
double ModelCorrespondenceFinder::cell_side() const {
  return certificate_radius_ > 0.0 ? 0.25 * certificate_radius_ : 1.0;
}

void ModelCorrespondenceFinder::reset(std::size_t scan_size) {
  hints_.assign(scan_size, engine::ProjectionHint{});
  atlas_.reset(cell_side());
}

// The point lies beyond an open edge of the model when its foot is on a face boundary (a trim
// edge, as the engine reports, or the surface's domain boundary) and the offset is not along the
// normal (an interior-type foot, e.g. on a closed seam, has p - foot parallel to the normal).
bool ModelCorrespondenceFinder::beyond_edge(std::size_t k, const engine::Vec3& p) const {
  const int entity = results_.entity[k];
  const double distance = results_.distance[k];
  if (entity < 0 || !(distance > 0.0)) return false;
  const auto off_normal = [&] {
    return std::abs((p - results_.foot[k]).dot(results_.normal[k])) < (1.0 - 1e-6) * distance;
  };
  if (results_.on_trim_edge[k]) return off_normal();
  const engine::NurbsSurface& s = projector_.model().model().surfaces[entity];
  const engine::ParamInterval du = s.domain_u();
  const engine::ParamInterval dv = s.domain_v();
  const double u = results_.u[k];
  const double v = results_.v[k];
  const double eps = 1e-12;
  const bool on_edge = u <= du.lo + eps * du.width() || u >= du.hi - eps * du.width() ||
                       v <= dv.lo + eps * dv.width() || v >= dv.hi - eps * dv.width();
  return on_edge && off_normal();
}

void ModelCorrespondenceFinder::find(const CorrespondenceQuery& query,
                                     std::span<Correspondence> out) {
  const std::size_t n = query.points.size();
  auto scan_index = [&](std::size_t k) {
    return query.scan_indices.empty() ? k : query.scan_indices[k];
  };
  // Certificates are made on the coarse stages' subsamples once the solver expects small moves:
  // the full-resolution stage then borrows them for the points between (about 90% of its first
  // pass). Making one costs about two cold projections, so at full resolution, where ICP
  // usually ends after one more pass, they are used but not made.
  const bool subsample = !query.scan_indices.empty() && query.scan_indices.size() < hints_.size();
  const bool certify = subsample && query.expected_motion < 0.5 * certificate_radius_;
  // Hints live by scan index; the projector wants them by query position. A full-resolution
  // query in scan order uses them in place (no copy of ~64 bytes per point).
  bool identity = true;
  std::size_t needed = n;
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t s = scan_index(k);
    identity = identity && s == k;
    needed = std::max(needed, s + 1);
  }
  if (hints_.size() < needed) hints_.resize(needed);
  const auto gather = [&](std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      // In place only in scan order (k == s, one writer per entry); otherwise a copy, so that
      // a query that names a scan point twice cannot race on its hint.
      engine::ProjectionHint& h = identity ? hints_[k] : query_hints_[k];
      if (!identity) h = hints_[scan_index(k)];
      // A point whose own certificate does not cover it borrows a neighbour's, if one does.
      if (!h.certificate.covers(query.points[k])) {
        if (const engine::ProjectionHint* b = atlas_.find(query.points[k])) h = *b;
      }
    }
  };
  if (!identity) query_hints_.resize(n);
  if (query.parallel) {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 4096),
        [&](const tbb::blocked_range<std::size_t>& r) { gather(r.begin(), r.end()); });
  } else {
    gather(0, n);
  }
  const std::span<const engine::ProjectionHint> hints =
      identity ? std::span<const engine::ProjectionHint>(hints_).first(n)
               : std::span<const engine::ProjectionHint>(query_hints_);
  engine::ProjectionOptions options;
  options.max_distance = query.max_distance;
  options.certify = certify;
  options.certificate_radius = certificate_radius_;
  const auto points = engine::PointView::of(query.points);
  if (query.parallel) {
    projector_.project(points, options, results_, hints, &counters_);
  } else {
    projector_.project_serial(points, options, results_, hints, &counters_);
  }
  // Answers and next hints per point: in parallel for a query in scan order (one writer per
  // hint); otherwise serially, so that a query naming a scan point twice cannot race on it.
  const auto answer = [&](std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      Correspondence& c = out[k];
      c.valid = results_.status[k] == engine::ProjectionStatus::ok;
      if (!c.valid) continue;
      c.foot = results_.foot[k];
      c.normal = results_.normal[k];
      c.distance = results_.distance[k];
      c.on_boundary = beyond_edge(k, query.points[k]);
      hints_[scan_index(k)] = results_.hint(k);
    }
  };
  if (query.parallel && identity) {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 4096),
        [&](const tbb::blocked_range<std::size_t>& r) { answer(r.begin(), r.end()); });
  } else {
    answer(0, n);
  }
  // New certificates (made only when certifying; anchored at this query's point) join the
  // atlas, in query order (the atlas is not thread-safe, and its order decides which of two
  // covering certificates a later point borrows).
  if (certify) {
    for (std::size_t k = 0; k < n; ++k) {
      if (results_.status[k] != engine::ProjectionStatus::ok) continue;
      const engine::WarmCertificate& c = results_.certificate[k];
      if (c.radius > 0.0f && c.anchor == query.points[k].cast<float>()) {
        atlas_.insert(hints_[scan_index(k)]);
      }
    }
  }
}

}  // namespace nurbsreg::icp
