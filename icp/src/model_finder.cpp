#include "nurbsreg/icp/model_finder.hpp"

namespace nurbsreg::icp {

ModelCorrespondenceFinder::ModelCorrespondenceFinder(const engine::PreparedModel& model)
    : projector_(model) {}

void ModelCorrespondenceFinder::reset(std::size_t scan_size) {
  hints_.assign(scan_size, engine::ProjectionHint{});
}

void ModelCorrespondenceFinder::find(const CorrespondenceQuery& query,
                                     std::span<Correspondence> out) {
  const std::size_t n = query.points.size();
  auto scan_index = [&](std::size_t k) {
    return query.scan_indices.empty() ? k : query.scan_indices[k];
  };
  query_hints_.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t s = scan_index(k);
    query_hints_[k] = s < hints_.size() ? hints_[s] : engine::ProjectionHint{};
  }
  engine::ProjectionOptions options;
  options.max_distance = query.max_distance;
  const auto points = engine::PointView::of(query.points);
  if (query.parallel) {
    projector_.project(points, options, results_, query_hints_, &counters_);
  } else {
    projector_.project_serial(points, options, results_, query_hints_, &counters_);
  }
  for (std::size_t k = 0; k < n; ++k) {
    Correspondence& c = out[k];
    c.valid = results_.status[k] == engine::ProjectionStatus::ok;
    if (!c.valid) continue;
    c.foot = results_.foot[k];
    c.normal = results_.normal[k];
    c.distance = results_.distance[k];
    const std::size_t s = scan_index(k);
    if (s >= hints_.size()) hints_.resize(s + 1);
    hints_[s] = results_.hint(k);
  }
}

}  // namespace nurbsreg::icp
