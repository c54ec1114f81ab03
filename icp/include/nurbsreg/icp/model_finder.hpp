#pragma once
// The closest-point step on a NURBS model: the engine's exact projection, warm-started per scan
// point from its previous foot (surface, u, v). Hints only speed the search up; every
// correspondence is the exact closest point (DESIGN.md "Engine", "ICP").
//
// Once the solver expects small moves (CorrespondenceQuery::expected_motion below half the
// certificate radius), projections also make warm certificates (engine::WarmCertificate): the
// next iterations then answer each point with one Newton on one patch. Points without a
// certificate of their own (the full-resolution stage's points that the coarse stages did not
// use) borrow a neighbour's from a CertificateAtlas.

#include <vector>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/icp/certificate_atlas.hpp"
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
  // Radius cap of the certificates (engine::ProjectionOptions::certificate_radius): 1% of the
  // model's bounding-box diagonal, so that a certificate made on a 10% subsample usually covers
  // the points between.
  double certificate_radius() const { return certificate_radius_; }

 private:
  bool beyond_edge(std::size_t k, const engine::Vec3& p) const;
  double cell_side() const;

  engine::Projector projector_;
  engine::FrameVector<engine::ProjectionHint> hints_;        // by scan index
  engine::FrameVector<engine::ProjectionHint> query_hints_;  // by query position (reused)
  engine::ProjectionResults results_;
  engine::ProjectionCounters counters_;
  double certificate_radius_ = 0.0;
  CertificateAtlas atlas_;
};

}  // namespace nurbsreg::icp
