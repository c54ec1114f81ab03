#pragma once
// The closest-point step on a NURBS model: the engine's exact projection, warm-started per scan
// point from its previous foot (surface, u, v). Hints only speed the search up; every
// correspondence is the exact closest point (DESIGN.md "Engine", "ICP").
//
// Hints are the previous find()'s answers (no hint array per scan point): read in place from
// its results when a query names the same scan points as the one before (the iterations of one
// stage); otherwise (the first query of a coarse-to-fine stage) copied out of them for the
// points the two queries share, which are found through a position per scan point (4 bytes).
// Only the previous query's answers carry over: a scan point left out of it starts afresh.
//
// Once the solver expects small moves (CorrespondenceQuery::expected_motion below half the
// certificate radius), projections also make warm certificates (engine::WarmCertificate): the
// next iterations then answer each point with one Newton on one patch. Points without a
// certificate of their own (the full-resolution stage's points that the coarse stages did not
// use) borrow a neighbour's from a CertificateAtlas, looked up before the projection (a pointer
// per query point). A borrowed certificate replaces the point's own hint for that query; when it
// does not prove the answer, the point borrows no more until reset() and keeps its own previous
// answer as its hint (a byte per scan point): on thin walls and near face boundaries the same
// neighbour's certificate would fail again, and each failure costs the lookup, a Newton on the
// neighbour's box and a search without the point's own warm start.
//
// A large query is answered in spatial order (engine::spatial_order of its points, computed when
// the query's scan points change and kept over the iterations that repeat them): the per-point
// state (the answers that are the next hints, the borrowed certificates) is stored in that order,
// so each pass reads and writes it in sequence, and consecutive points touch the same patches.
// A scan in no spatial order (synthetic, merged, subsampled) otherwise sends every access to a
// random place in arrays of a million entries. Only the storage moves: each answer depends on
// its point and hint alone and the atlas takes new certificates in query order, so the answers
// are the same bits; find() writes them and last_results() hands them out in query order.

#include <cstdint>
#include <utility>
#include <vector>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/spatial_order.hpp"
#include "nurbsreg/icp/certificate_atlas.hpp"
#include "nurbsreg/icp/correspondence.hpp"

namespace nurbsreg::icp {

// The radius cap of the certificates a finder makes on `model` for a scan of `scan_size` points:
// 1% of the diagonal of its trimmed faces, so that a certificate made on a 10% subsample usually
// covers the points between. For scans of kWidthCapPoints points and more, at most
// kCertificateWidths times the narrow width of the patches where half of the model's area lies
// (certificate_radius.cpp: a certificate reaches no further than the patches about its anchor;
// on smaller scans the certificates that this lets the subsamples make cost more than the few
// full-resolution passes save).
inline constexpr double kCertificateWidths = 4.0;
inline constexpr std::size_t kWidthCapPoints = 500000;
// A full-resolution pass's own certificates (ModelCorrespondenceFinder::answer): their radius in
// multiples of the motion the solver expects before the next pass (its last step's): the step
// from the last subsample's pose to all points' can be about twice the subsample's last one.
inline constexpr double kOwnCertificateMotions = 4.0;
// A clearance certificate's radius, in the same multiples: its search's margin is twice it, and
// the margin is what the search pays for (the proof needs d + 2 m within the clearance for a
// move m, the margin covers a move as large as the last step).
inline constexpr double kClearanceMotions = 1.0;
// ... and only on queries of at least this many points: not on the global stage's short ICPs
// (300 and 1,500 points a hypothesis), whose hypotheses move on or are dropped.
inline constexpr std::size_t kClearanceMinPoints = 4096;
// ... made only when the solver expects at least this many passes after the one that makes
// them: making one costs about one to two cold searches beyond the answer's own (NIST CTC-02
// about one, linkrods two), and each later pass it proves saves about one.
inline constexpr int kOwnCertificateLaterQueries = 2;
double certificate_radius_for(const engine::PreparedModel& model, std::size_t scan_size);
// The rule itself, given the two caps (1% of the diagonal; patch_width_cap).
inline double certificate_radius_for(std::size_t scan_size, double share_cap, double width_cap) {
  return scan_size >= kWidthCapPoints && width_cap < share_cap ? width_cap : share_cap;
}
// How many patches beyond its foot's a certificate's box may reach on each side
// (engine::ProjectionOptions::certificate_span), for a scan of `scan_size` points: the most for
// scans of kWidthCapPoints and more, where each certificate a subsample makes serves about ten
// points of every full-resolution pass (on the IEA blade's 5 cm strips, one patch beyond the
// foot's held the radius to a fraction of the scan's spacing); one otherwise: on a
// 50,000-point scan the wider boxes cost the blade's certifying passes more than its two
// full-resolution passes save (bench/README.md, issue 26's tenth pass).
inline int certificate_span_for(std::size_t scan_size) {
  return scan_size >= kWidthCapPoints ? engine::kMaxCertificateSpan : 1;
}
// The patches' cap alone: kCertificateWidths times their area-weighted median narrow width
// (infinity for a model without patches).
double patch_width_cap(const engine::PreparedModel& model);

class ModelCorrespondenceFinder final : public CorrespondenceFinder {
 public:
  // `model` must outlive the finder. The finder is not thread-safe itself (it keeps the hints);
  // its find() projects in parallel with TBB when the query allows.
  explicit ModelCorrespondenceFinder(const engine::PreparedModel& model);
  // It keeps a reference to the model: a temporary would dangle.
  ModelCorrespondenceFinder(const engine::PreparedModel&&) = delete;

  void reset(std::size_t scan_size) override;
  // A stream of frames of one model (a service session): reset() keeps the certificates made so
  // far, so a frame's first passes borrow those of the frames before instead of searching the
  // model from scratch. A certificate speaks for a ball of space around its anchor on this model,
  // whichever scan asks, so the answers stay the exact closest points; only the Newton starts,
  // and with them the last bits of a foot, may differ from a fresh finder's. The atlas keeps one
  // certificate per cell, so it is bounded by the model's size, not by the number of frames.
  void keep_certificates(bool keep) { keep_certificates_ = keep; }
  bool keeps_certificates() const { return keep_certificates_; }
  void find(const CorrespondenceQuery& query, std::span<Correspondence> out) override;

  // The projection results of the last find() (entity, u, v, signed distance, ...), in query
  // order: what `align --aligned` writes per point. Without feet and normals (foot and normal
  // are empty): those went straight into find()'s correspondences.
  // After a find() in spatial order, put back in query order on the first call, without the
  // certificates (they stay with the finder: 44 bytes a point that no caller reads).
  const engine::ProjectionResults& last_results() const;
  const engine::ProjectionCounters& last_counters() const { return counters_; }
  // Scan point s borrowed an atlas certificate since reset() that did not prove its answer, so
  // it borrows no more (for tests and benchmarks).
  bool stopped_borrowing(std::size_t s) const {
    return s < borrow_failed_.size() && borrow_failed_[s] != 0;
  }
  // Radius cap of the certificates (engine::ProjectionOptions::certificate_radius):
  // certificate_radius_for(model, the scan size of the last reset(); before any, 0).
  double certificate_radius() const { return certificate_radius_; }
  // Certificates the atlas holds (lent to the points of later queries).
  std::size_t atlas_size() const { return atlas_.size(); }
  // Certificates the atlas keeps per cell (CertificateAtlas::reset): where convexity limits
  // certificates to a fraction of the cap (small bores and tori, rational), one anchor a cell
  // covers only the points within that fraction of it (the cells hold one to three anchors of a
  // 10% subsample).
  static constexpr int kAtlasHintsPerCell = 4;
  // Queries of this many points and more are answered in spatial order (below, the arrays stay in
  // cache anyway and ordering would cost more than it saves), when they may run in parallel, on
  // models of kSpatialOrderMinPatches patches and more: there the patches a pass touches do not
  // stay in a core's cache, and points that come one after another on the same patches save
  // more than putting each answer in its place costs; on the smaller parts (a few hundred
  // patches) the two are even or the order loses (bench/README.md, issue 26's fifteenth pass).
  static constexpr std::size_t kSpatialOrderMin = 8192;
  static constexpr std::size_t kSpatialOrderMinPatches = 500;
  // Whether large queries are answered in spatial order (by default, as the model's size says);
  // the answers are the same bits either way (tests compare the two).
  void use_spatial_order(bool use) { use_spatial_order_ = use; }
  bool uses_spatial_order() const { return use_spatial_order_; }

 private:
  // find() itself, which forgets the previous query when this one throws.
  void answer(const CorrespondenceQuery& query, std::span<Correspondence> out);
  bool beyond_edge(std::size_t k, const engine::Vec3& p, const Correspondence& c) const;
  double cell_side() const;
  // The previous query's answers as hints for this one (HintSource in the .cpp); after the
  // projection, remember_query clears what it set up and remembers this query.
  struct HintSource;
  HintSource prepare_hints(const CorrespondenceQuery& query, bool repeats);
  void remember_query(const CorrespondenceQuery& query, bool repeats);
  // After the projection: marks the points whose borrowed certificate did not prove them.
  void remember_failed_borrows(const CorrespondenceQuery& query);
  bool repeats_previous_query(const CorrespondenceQuery& query) const;
  std::size_t previous_index(std::size_t j) const {
    return previous_all_ ? j : previous_indices_[j];
  }
  // Where query point k's answer is stored: its position in the order of the last query (p),
  // and back (query_index).
  std::size_t query_index(std::size_t p) const { return ordered_ ? order_[p] : p; }
  // A new query's order (or none): order_, ordered_.
  void choose_order(const CorrespondenceQuery& query);
  // The query's points in that order (ordered_points_), every call.
  void gather_points(const CorrespondenceQuery& query);
  // The points as the projection takes them: ordered_points_ or the query's own.
  std::span<const engine::Vec3> stored_points(const CorrespondenceQuery& query) const;
  // New certificates into the atlas, in query order.
  void insert_made_certificates(std::span<const engine::Vec3> points);

  engine::Projector projector_;
  engine::ProjectionResults results_;
  engine::ProjectionCounters counters_;
  double certificate_radius_ = 0.0;
  // certificate_radius_for's two caps (1% of the diagonal; the patches' widths), computed once.
  double share_cap_ = 0.0, width_cap_ = 0.0;
  std::size_t scan_size_ = 0;
  // The scan points of the previous query since reset(): all of them in order
  // (previous_all_), or previous_indices_.
  bool has_previous_ = false;
  bool previous_all_ = false;
  std::size_t previous_size_ = 0;
  engine::FrameVector<std::size_t> previous_indices_;
  // For a query that differs from the previous one: the previous answers' hints (by previous
  // position) and, per scan point, its previous position or kNoPosition (kept all kNoPosition
  // between calls).
  static constexpr std::uint32_t kNoPosition = 0xffffffffu;
  engine::FrameVector<engine::ProjectionHint> carried_;
  engine::FrameVector<std::uint32_t> previous_position_;
  // Per query point: the atlas certificate it borrows, or null (HintSource::borrowed).
  engine::FrameVector<const engine::ProjectionHint*> borrowed_;
  // The atlas lookups' order, their points in it, and its scratch (CertificateAtlas::lookup_order).
  CertificateAtlas::LookupOrder lookup_order_;
  // Per query point: 1 when it has no certificate of its own that covers it (and may borrow).
  std::vector<std::uint8_t> needs_lookup_;
  // Per scan point: 1 once a certificate it borrowed did not prove its answer (it borrows no
  // more until reset()); sized with previous_position_.
  engine::FrameVector<std::uint8_t> borrow_failed_;
  CertificateAtlas atlas_;
  bool keep_certificates_ = false;
  // The spatial order of the last query (position -> query index) when ordered_, its scratch,
  // and that query's points in it.
  bool use_spatial_order_ = false;
  bool ordered_ = false;
  engine::FrameVector<std::uint32_t> order_;
  engine::SpatialOrderScratch order_scratch_;
  engine::FrameVector<engine::Vec3> ordered_points_;
  engine::FrameVector<Correspondence> ordered_answers_;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> made_;  // (query index, position)
  // results_ in query order, made by last_results() after a find() in spatial order.
  mutable engine::ProjectionResults query_order_results_;
  mutable bool query_order_current_ = false;
};

}  // namespace nurbsreg::icp
