#pragma once
// The closest-point step on a NURBS model: the engine's exact projection, warm-started per scan
// point from its previous foot (surface, u, v). Hints only speed the search up; every
// correspondence is the exact closest point (DESIGN.md "Engine", "ICP").

#include <vector>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/icp/correspondence.hpp"

namespace nurbsreg::icp {

class ModelCorrespondenceFinder final : public CorrespondenceFinder {
 public:
  // `model` must outlive the finder. The finder is not thread-safe itself (it keeps the hints);
  // its find() projects in parallel with TBB when the query allows.
  explicit ModelCorrespondenceFinder(const engine::PreparedModel& model);

  void reset(std::size_t scan_size) override;
  void find(const CorrespondenceQuery& query, std::span<Correspondence> out) override;

  // The full projection results of the last find() (entity, u, v, signed distance, ...), in
  // query order: what `align --aligned` writes per point.
  const engine::ProjectionResults& last_results() const { return results_; }
  const engine::ProjectionCounters& last_counters() const { return counters_; }

 private:
  engine::Projector projector_;
  std::vector<engine::ProjectionHint> hints_;        // by scan index
  std::vector<engine::ProjectionHint> query_hints_;  // by query position (reused)
  engine::ProjectionResults results_;
  engine::ProjectionCounters counters_;
};

}  // namespace nurbsreg::icp
