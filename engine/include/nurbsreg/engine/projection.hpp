#pragma once
// Batch projection of point frames onto a prepared model: exact closest point, parameters,
// distance and normal for every point, in parallel (TBB).
//
// Trimmed faces (NurbsSurface::trim_loops): the closest point of the face, i.e. the best of its
// interior points inside the trimmed region and the points of its boundary edges (the 3-D trim
// edges, projected with the curve projector). A foot on an edge reports (u, v) = uv(t) of its
// trim curve at the edge's parameter t, and the surface normal there. A warm-start hint on a
// trimmed face seeds the search only with face points.
//
// Threads: `Projector::project` runs a tbb::parallel_for in the caller's task arena; the number
// of threads belongs to the application (tbb::global_control / task_arena). Results are written
// by index and each point is computed independently, so they are bit-identical for any thread
// count and equal to `project_serial`.
// Allocation: a Projector owns per-thread scratch that grows during the first frame and is then
// reused; the hot path allocates nothing per point. ProjectionResults are caller-owned and only
// resized.

#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <type_traits>
#include <vector>

#include "nurbsreg/engine/large_buffer.hpp"
#include "nurbsreg/engine/prepared_model.hpp"

namespace nurbsreg::engine {

enum class ProjectionTarget : std::uint8_t { surfaces, curves };

enum class ProjectionStatus : std::uint8_t {
  ok,                   // exact closest point found
  skipped_nonfinite,    // the input point had a NaN or infinite coordinate
  no_geometry,          // the model has no entity of the requested target kind
  beyond_max_distance,  // nothing of the model within ProjectionOptions::max_distance
};

// A proof, made while projecting an anchor point a, that lets later queries q near a skip the
// search (ProjectionOptions::certify). With P the patch of a's closest point and N a box of P's
// local parameters around it (all of P when possible), or, on a surface that is C1 across its
// patch edges (PreparedModel::surface_c1), a box that reaches into P's neighbours (convexity is
// then proven on each patch's part of N, which C1 makes convexity on N):
//   - F_q = |S - q|^2 is strictly convex on N for every q with |q - a| <= radius (the clipping's
//     convexity test on F_a's Bézier coefficients over N, widened by the most the coefficients'
//     second differences can move when the point moves by `radius`), so Newton's KKT point on N
//     is N's minimum for every such q; for a foot on P's edge or corner (a point beyond the
//     surface's boundary), F_q strictly increasing away from that edge on N and convex along it
//     serves instead;
//   - everything of the model outside N is at least `clearance` away from a: Bézier bounds over
//     the rest of N's patches, and an exact best-first search over the rest of the model against
//     alpha = (d_a + 2 radius)^2.
// The projector trusts a certificate only for the PreparedModel that made it (`model`).
// For a query q with |q - a| <= radius whose Newton minimum on N has distance d, everything else
// is at least clearance - |q - a| away by the triangle inequality: d + |q - a| <= clearance
// proves d is the model's distance without looking at anything else. On a trimmed face N is a
// box the face's region proves inside it (TrimRegion::classify), so N's points are face points
// and the face's trim edges are items of the search. On a rational patch (N within the patch,
// interior feet) convexity is proven for G = N_q - m D, the numerator less the query's value
// times the denominator, for every m a proof can meet (proofs/warm_certificate.cpp).
// radius == 0: none (patch == kTried: a certificate was sought at
// `anchor` and could not be made; the projector does not retry within the radius cap of it),
// or, with patch >= 0 and clearance > 0, a clearance certificate (clearance_only(),
// ProjectionOptions::certify_clearance): no box and no convexity claim, only "everything of the
// model other than patch P is at least `clearance` away from a". A query q whose hint is on P
// gets P's own exact minimum d (its Newton, then P's clipping, face part only on a trimmed face:
// its trim edges are other items), and d + |q - a| <= clearance proves it the model's.
inline constexpr int kMaxCertificateSpan = 3;  // ProjectionOptions::certificate_span

struct WarmCertificate {
  static constexpr std::int32_t kTried = -2;
  // Single precision keeps hints small (frames of millions of points): the anchor is the query
  // point rounded to float, with radius and clearance reduced by that rounding and rounded down,
  // so the proof holds as stated for the stored anchor.
  Eigen::Vector3f anchor = Eigen::Vector3f::Zero();
  float radius = 0.0f;
  float clearance = 0.0f;
  std::int32_t patch = -1;  // PreparedModel patch index
  // N in P's grid coordinates: P is [0, 1]^2, the patch i spans after it in u and j in v
  // [i, i + 1] x [j, j + 1] (|i|, |j| at most ProjectionOptions::certificate_span).
  float s0 = 0.0f, s1 = 1.0f, t0 = 0.0f, t1 = 1.0f;
  std::uint32_t model = 0;  // PreparedModel::serial() of the model that made it

  double distance_to_anchor(const Vec3& p) const { return (p - anchor.cast<double>()).norm(); }
  // p lies in the ball the certificate speaks for.
  bool covers(const Vec3& p) const { return radius > 0.0f && distance_to_anchor(p) <= radius; }
  // A clearance certificate (above): the rest of the model beyond patch P only.
  bool clearance_only() const { return radius == 0.0f && patch >= 0 && clearance > 0.0f; }
};

// Where a point's closest point was last time (e.g. the previous ICP iteration): entity index
// and parameters, and optionally the certificate made then. entity < 0 means no hint. A hint
// only speeds the search up: the answer is exact whatever it says (a certificate is checked
// against the query point, so it may come from any earlier query).
struct ProjectionHint {
  ProjectionHint() = default;
  ProjectionHint(std::int32_t entity_, double u_, double v_, WarmCertificate certificate_ = {})
      : entity(entity_), u(u_), v(v_), certificate(certificate_) {}

  std::int32_t entity = -1;
  double u = 0.0;
  double v = 0.0;
  WarmCertificate certificate;
};

// Structure of arrays, one entry per input point, written by index (FrameVector: large frames'
// arrays faulted in on all threads, large_buffer.hpp).
struct ProjectionResults {
  // Empty when ProjectionOptions::foot_sink took the feet and normals (as `normal`).
  FrameVector<Vec3> foot;
  FrameVector<double> distance;         // >= 0, Euclidean
  FrameVector<double> signed_distance;  // positive on the side the normal points to (0 side: +)
  FrameVector<std::int32_t> entity;     // surface (or curve) index in the model, -1 if none
  FrameVector<double> u;
  FrameVector<double> v;  // 0 for curves
  // Unit surface normal at the foot: Su x Sv, or -(Su x Sv) for a reversed face
  // (NurbsSurface::reversed); 0 for curves.
  FrameVector<Vec3> normal;
  FrameVector<ProjectionStatus> status;
  // 1 when the foot lies on a trim edge of its face (a trimmed face's boundary, where the
  // closest point need not be an orthogonal projection); 0 otherwise.
  FrameVector<std::uint8_t> on_trim_edge;
  // The certificate that proves this point's answer: the hint's, when it still held (so its
  // anchor may be an earlier point), or a new one (ProjectionOptions::certify); radius 0 if none.
  // Empty after a frame that neither certified nor had hints (no certificate can exist then;
  // 44 bytes a point saved).
  FrameVector<WarmCertificate> certificate;

  std::size_t size() const { return status.size(); }
  // Every array to n entries; with feet == false, foot and normal to none, with certificates ==
  // false, certificate to none (their memory is kept for a later frame).
  void resize(std::size_t n, bool feet = true, bool certificates = true);
  // Copies `part` into entries [offset, offset + part.size()) (frames projected in blocks).
  void copy_from(const ProjectionResults& part, std::size_t offset);
  // Copies entry k of `part` into entry ids[k] (a few points projected again). A field this one
  // does not hold is skipped; feet or normals `part` lacks leave those entries as they were,
  // certificates it lacks leave none there (an old certificate would not match the new answer).
  void scatter_from(const ProjectionResults& part, std::span<const std::size_t> ids);
  // The same with 32-bit entries (an engine::spatial_order order: answer k of the ordered
  // points to the point's own place).
  void scatter_from(const ProjectionResults& part, std::span<const std::uint32_t> ids);
  ProjectionHint hint(std::size_t i) const {
    if (status[i] != ProjectionStatus::ok) return ProjectionHint{};
    return ProjectionHint{entity[i], u[i], v[i],
                          certificate.empty() ? WarmCertificate{} : certificate[i]};
  }
};

// Where a frame's feet and normals go instead of ProjectionResults::foot and ::normal, which then
// stay empty: e.g. straight into the caller's own per-point records, which saves a copy and
// 48 bytes a point. write(data, i, foot, normal) is called once for every point whose status is
// `ok`, from the thread that projects point i; points with another status get no call.
struct FootSink {
  void* data = nullptr;
  void (*write)(void* data, std::size_t i, const Vec3& foot, const Vec3& normal) = nullptr;

  explicit operator bool() const { return write != nullptr; }
};

struct ProjectionOptions {
  ProjectionTarget target = ProjectionTarget::surfaces;
  // Points per parallel task.
  std::size_t grain = 256;
  // Process a large frame (project(), 8192 points and more) in the Morton order of a grid over
  // its points instead of index order: points that come in no spatial order then reuse the
  // hierarchy nodes and patches the previous point touched (15-30% faster on a 1,369-patch panel).
  // Results are unchanged and still by index; false processes in index order.
  bool locality_order = true;
  // Points with nothing of the model within this distance get status beyond_max_distance
  // without an exact foot: the search starts with alpha = max_distance^2, so far points (ICP
  // outliers) cost almost nothing. Infinity: every point gets its exact closest point.
  double max_distance = std::numeric_limits<double>::infinity();
  // Make a WarmCertificate for every point whose answer is not already proven by its hint's
  // (ProjectionResults::certificate), so that the next frame's hints (ProjectionResults::hint)
  // carry them: a query within `certificate_radius` of its anchor then costs one Newton on one
  // patch. Making one costs a second, wider search (about a cold projection), so it pays when
  // points come back near where they were (ICP iterations, tracking frames).
  bool certify = false;
  // Without certify: give every point whose answer no hint proved a clearance certificate
  // (WarmCertificate::clearance_only) for moves up to `certificate_radius`: its search also
  // bounds everything but the foot's patch up to twice that beyond its distance: a wider walk,
  // but no convexity proof and no bounds beside a box; a later query near it then clips that
  // one patch instead of searching the model. For the passes that a solver expects to repeat
  // once more on the same points with small moves (ICP's last stage).
  bool certify_clearance = false;
  // Largest anchor radius sought (the certificate's radius is also limited by convexity); <= 0:
  // 0.1% of the diagonal of the model's trimmed faces' box (PreparedModel::geometry_bounds).
  double certificate_radius = 0.0;
  // How many patches beyond the foot's, on each side, a certificate's box may reach on a surface
  // of several patches (1 .. kMaxCertificateSpan). Wider boxes serve larger balls where the
  // patches are narrow against the radius sought (the IEA blade's 5 cm strips), but cost more to
  // make and widen the certifying search: worth it when each certificate serves many later
  // queries (ICP on a million points borrows a subsample's; ModelCorrespondenceFinder).
  int certificate_span = 1;
  // Prove answers with the model's reach bounds where they can (PreparedModel::ReachCell: one
  // Newton from the hint or the cold seed, no search), when the model has them
  // (PreparedModel::prepare_reach_bounds). false: only certificates and the search (to measure
  // or test those alone).
  bool reach_bounds = true;
  // A large cold frame (no hints, neither certify nor certify_clearance, locality_order): each
  // point's search also lists every item of the model within `chain_margin` beyond its answer
  // (a near list, Projector::NearList), and the next points of the locality order, taken on a
  // grid fine enough that they lie close together, clip only the listed items while the list
  // still proves their answers (distance + distance to the list's point <= its clearance):
  // most points then skip the hierarchy walk. The answers are the same exact closest points;
  // false walks the hierarchy for every point.
  bool chain_cold = true;
  // The near lists' margin; <= 0: chain_margin_for the frame's own order.
  double chain_margin = 0.0;
  // With chain_cold and chain_margin > 0: the frame's points already come in a fine spatial
  // order (a block of one whole cloud's order, io::project_cloud), and are chained as they come,
  // a chain starting at every multiple of kChainLength of the frame. A cloud cut into blocks of
  // multiples of kChainLength then gets the same answers whatever the block size.
  bool chain_in_index_order = false;
  // Empty: feet and normals go to ProjectionResults. Set: to the sink only (see FootSink).
  FootSink foot_sink;
};

// Points per chain of a chained cold frame (ProjectionOptions::chain_cold): a chain starts
// afresh at every multiple of it, whatever the tasks the frame was cut into.
inline constexpr std::size_t kChainLength = 256;

// Work counters summed over a frame (for benchmarks and progress logs).
struct ProjectionCounters {
  std::uint64_t points = 0;
  std::uint64_t skipped = 0;
  std::uint64_t patches_visited = 0;
  std::uint64_t subdivisions = 0;
  std::uint64_t newton_iterations = 0;  // of the per-patch box-constrained Newton (surfaces)
  std::uint64_t certified = 0;          // answers proven by the hint's WarmCertificate
  // Answers proven by the model's reach bounds (PreparedModel::ReachCell) after one Newton from
  // the hint or the cold seed: no search.
  std::uint64_t reach_proven = 0;
  std::uint64_t certificates_made = 0;  // new WarmCertificates (ProjectionOptions::certify)
  // Chained cold frames (ProjectionOptions::chain_cold): answers proven by the previous points'
  // near list (no hierarchy walk), and near lists made.
  std::uint64_t listed = 0;
  std::uint64_t lists_made = 0;
  // Where patches_visited went (surfaces; the profile of bench/cad/real_models_bench): trim-edge
  // pieces, patches clipped against their face's region, rational patches; and the trimmed
  // clipping's sub-patches dropped as outside and candidates rejected as outside the region.
  std::uint64_t edge_pieces_visited = 0;
  std::uint64_t trimmed_patches_visited = 0;
  std::uint64_t rational_patches_visited = 0;
  std::uint64_t region_drops = 0;
  std::uint64_t region_rejections = 0;
};

// A frame of points without copying: any container that can hand out point i.
struct PointView {
  const void* data = nullptr;
  std::size_t count = 0;
  Vec3 (*at)(const void* data, std::size_t i) = nullptr;

  std::size_t size() const { return count; }
  Vec3 operator[](std::size_t i) const { return at(data, i); }

  static PointView of(std::span<const Vec3> points) {
    return {points.data(), points.size(),
            [](const void* d, std::size_t i) { return static_cast<const Vec3*>(d)[i]; }};
  }
};

// The near lists' margin for points taken in `order` (ProjectionOptions::chain_margin): a few
// times the median distance between consecutive points, so that a list stays valid for the next
// few points while it stays short (the items within the margin of a point's answer). 0 when
// there is no step to measure.
double chain_margin_for(PointView points, std::span<const std::uint32_t> order);

// The hints of a frame without a per-point array: any source that can hand out point i's hint
// (empty: no hints). The projector calls at(data, i) at most once per point (not for skipped
// points), from the thread that projects point i, before it writes any result of point i. So
// the source may read the very ProjectionResults being written (the previous pass's answers, in
// place: ProjectionResults::hint(i)), which saves a frame-sized hint array (~70 bytes a point).
struct HintView {
  using Source = ProjectionHint (*)(const void* data, std::size_t i);

  HintView() = default;
  HintView(const void* data, std::size_t count, Source at) : data_(data), count_(count), at_(at) {}
  // An array of hints (any contiguous container of them).
  HintView(std::span<const ProjectionHint> hints)  // NOLINT: implicit by design
      : HintView(hints.data(), hints.size(), [](const void* d, std::size_t i) {
          return static_cast<const ProjectionHint*>(d)[i];
        }) {}
  template <class Container>
  requires std::is_convertible_v<const Container&, std::span<const ProjectionHint>> HintView(
      const Container& hints)  // NOLINT: implicit by design
      : HintView(std::span<const ProjectionHint>(hints)) {}

  bool empty() const { return count_ == 0; }
  std::size_t size() const { return count_; }
  ProjectionHint operator[](std::size_t i) const { return at_(data_, i); }

 private:
  const void* data_ = nullptr;
  std::size_t count_ = 0;
  Source at_ = nullptr;
};

class Projector {
 public:
  // Keeps a reference to `model`, which must outlive the projector: a temporary is rejected.
  explicit Projector(const PreparedModel& model);
  Projector(const PreparedModel&&) = delete;
  ~Projector();
  Projector(const Projector&) = delete;
  Projector& operator=(const Projector&) = delete;

  // Projects every point; `hints` is empty or has one entry per point (std::invalid_argument
  // otherwise).
  void project(PointView points, const ProjectionOptions& options, ProjectionResults& out,
               HintView hints = {}, ProjectionCounters* counters = nullptr);
  // The same on the calling thread only (debugging, and the reference for "parallel == serial").
  void project_serial(PointView points, const ProjectionOptions& options, ProjectionResults& out,
                      HintView hints = {}, ProjectionCounters* counters = nullptr);

  const PreparedModel& model() const { return model_; }

 private:
  struct ThreadState;
  struct Impl;
  struct OtherItems;
  struct NearList;
  // The state of one best-first search over the surfaces' hierarchy (the caller's variables).
  struct SurfaceSearch {
    SurfaceHit& best;
    int& surface;
    std::int64_t& patch;
    std::int64_t& edge;  // the best point is on this trim-edge piece (then patch is -1)
    double& edge_t;
    // A certifying search: also bounds every item but its answer (projection.cpp, OtherItems).
    OtherItems* others = nullptr;
    // A listing search (ProjectionOptions::chain_cold): also lists every item within the list's
    // margin beyond the answer.
    NearList* list = nullptr;
  };
  // Exact best-first search over patches and trim edges, improving search.best; skip_patch is
  // not visited (its minimum is already known), guess_patch's clipping starts Newton at
  // (guess_s, guess_t).
  void search_surfaces(const Vec3& p, SurfaceSearch& search, std::int64_t skip_patch,
                       std::int64_t guess_patch, double guess_s, double guess_t,
                       ThreadState& state) const;
  // The closest point among the items of `list` only (the walk's visits, in order of their
  // lower bounds), improving search.best.
  void search_list(const Vec3& p, SurfaceSearch& search, const NearList& list,
                   std::int64_t guess_patch, double guess_s, double guess_t,
                   ThreadState& state) const;
  // `others`: what the certifying search that found `best` learnt of the rest of the model.
  WarmCertificate make_certificate(const Vec3& p, const SurfaceHit& best, std::int64_t patch,
                                   std::int64_t edge, const OtherItems& others,
                                   ThreadState& state) const;
  // The clearance certificate (ProjectionOptions::certify_clearance) the same search allows: the
  // rest of the model beyond `patch`; none for a foot on a trim edge.
  WarmCertificate make_clearance_certificate(const Vec3& p, const SurfaceHit& best,
                                             std::int64_t patch, std::int64_t edge,
                                             const OtherItems& others, ThreadState& state) const;
  // Projects points order[begin, end) (or begin .. end - 1 when order is empty): per point the
  // input checks, then project_surface_point or project_curve_point (point_projection.cpp).
  void project_range(PointView points, const ProjectionOptions& options, ProjectionResults& out,
                     HintView hints, std::span<const std::uint32_t> order, std::size_t begin,
                     std::size_t end, ThreadState& state) const;
  // Projects the frame's points ids (a block of its locality order, no hints) into a block of
  // their own, then puts each answer at its point's index in `out`.
  void project_block(PointView points, const ProjectionOptions& options,
                     std::span<const std::uint32_t> ids, ProjectionResults& out,
                     ThreadState& state) const;
  // One finite point's answer written to `out` (its certificate too), or the status to write
  // as missing (beyond_max_distance).
  ProjectionStatus project_surface_point(const Vec3& p, const ProjectionHint* hint, std::size_t i,
                                         const ProjectionOptions& options, double certificate_cap,
                                         ProjectionResults& out, ThreadState& state) const;
  ProjectionStatus project_curve_point(const Vec3& p, const ProjectionHint* hint, std::size_t i,
                                       const ProjectionOptions& options, ProjectionResults& out,
                                       ThreadState& state) const;
  const PreparedModel& model_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace nurbsreg::engine
