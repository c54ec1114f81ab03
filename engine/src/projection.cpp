#include "nurbsreg/engine/projection.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "cpu_dispatch.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "spatial_order.hpp"
#include "warm_certificate.hpp"

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

struct Projector::ThreadState {
  SurfaceScratch surface_scratch;
  SurfaceProjectionStats surface_stats;
  CurveProjectionStats curve_stats;
  Bvh::Scratch bvh_scratch;
  ProjectionCounters counters;
};

struct Projector::Impl {
  tbb::enumerable_thread_specific<ThreadState> states;
  // The frame's processing order (ProjectionOptions::locality_order), reused across frames.
  FrameVector<std::uint32_t> order;
  SpatialOrderScratch order_scratch;
};

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

// What a certifying search learns of the items other than its answer, so that the certificate
// needs no second search: the walk prunes at (d + margin)^2 instead of d^2 (d: the best distance
// so far) and clips each item it visits against that threshold, so every item ends up either
// with its exact minimum recorded or proven at least (d_final + margin)^2 away (pruned, or
// clipped without a point below the threshold, which never falls below the final one). Kept:
// the kSlots smallest minima of distinct items (patch index, or -1 - edge piece), enough for "the
// nearest item other than those of a certificate's box N" (N spans up to 3 x 3 patches).
struct Projector::OtherItems {
  static constexpr std::int64_t kNone = std::numeric_limits<std::int64_t>::min();
  static constexpr int kSlots = 12;
  double margin = 0.0;
  // Ascending by minimum; unused slots at the end (kNone, infinity).
  std::int64_t item[kSlots];
  double minimum[kSlots];

  OtherItems() {
    std::fill(std::begin(item), std::end(item), kNone);
    std::fill(std::begin(minimum), std::end(minimum), std::numeric_limits<double>::infinity());
  }
  double threshold(double best_sq) const {
    const double d = std::sqrt(best_sq) + margin;
    return d * d;
  }
  void add(std::int64_t id, double value) {
    int k = 0;
    while (k < kSlots && item[k] != id && item[k] != kNone)
      ++k;
    if (k < kSlots && item[k] == id) {
      if (!(value < minimum[k])) return;
    } else {
      // A new item: it takes the last slot if it beats what is there (an item pushed out had a
      // minimum at least the last slot's, which only decreases: the last slot's minimum stays a
      // lower bound for every item not kept).
      k = kSlots - 1;
      if (!(value < minimum[k])) return;
      item[k] = id;
    }
    minimum[k] = value;
    for (; k > 0 && minimum[k] < minimum[k - 1]; --k) {
      std::swap(item[k], item[k - 1]);
      std::swap(minimum[k], minimum[k - 1]);
    }
  }
  // A lower bound of the minimum of every item for which `excluded(id)` is false: the smallest
  // recorded minimum of such an item, or the last slot's when every slot is excluded (infinity:
  // none below the threshold).
  template <typename Excluded>
  double excluding(Excluded&& excluded) const {
    for (int k = 0; k < kSlots; ++k) {
      if (item[k] == kNone || !excluded(item[k])) return minimum[k];
    }
    return minimum[kSlots - 1];
  }
  double excluding(std::int64_t id) const {
    return excluding([id](std::int64_t x) { return x == id; });
  }
};

namespace {

// Foot and normal of point i: to the sink, or to the results.
void write_foot(ProjectionResults& out, const FootSink& sink, std::size_t i, const Vec3& foot,
                const Vec3& normal) {
  if (sink) {
    sink.write(sink.data, i, foot, normal);
  } else {
    out.foot[i] = foot;
    out.normal[i] = normal;
  }
}

// Point i has no certificate (the array is empty when the frame can have none).
void clear_certificate(ProjectionResults& out, std::size_t i) {
  if (!out.certificate.empty()) out.certificate[i] = WarmCertificate{};
}

void write_missing(ProjectionResults& out, std::size_t i, ProjectionStatus status) {
  if (!out.foot.empty()) {  // empty when a FootSink takes the feet (it gets none here)
    out.foot[i] = Vec3::Constant(kNaN);
    out.normal[i] = Vec3::Zero();
  }
  out.distance[i] = kNaN;
  out.signed_distance[i] = kNaN;
  out.entity[i] = -1;
  out.u[i] = kNaN;
  out.v[i] = kNaN;
  out.on_trim_edge[i] = 0;
  out.status[i] = status;
}

// The default largest certificate radius: 0.1% of the model's size (ICP's late iterations and
// tracking frames move points far less; a larger radius makes each certificate's search wider).
double certificate_radius_cap(const ProjectionOptions& options, const PreparedModel& model) {
  return options.certificate_radius > 0.0 ? options.certificate_radius
                                          : 1e-3 * model.bounds().diagonal();
}

// The mark of a point for which no certificate could be made (WarmCertificate::kTried).
WarmCertificate tried_at(const Vec3& p) {
  WarmCertificate tried;
  tried.anchor = p.cast<float>();
  tried.patch = WarmCertificate::kTried;
  return tried;
}

bool valid_hint(const ProjectionHint* hint, std::size_t entities) {
  return hint != nullptr && hint->entity >= 0 &&
         static_cast<std::size_t>(hint->entity) < entities && std::isfinite(hint->u) &&
         std::isfinite(hint->v);
}

// Descent-only Newton over all of patch bp from best's local (s, t); best takes its point (s, t,
// u, v, squared distance, foot, normal). True when it ended at a KKT point of the patch.
bool newton_over_patch(const BezierPatch& bp, const Vec3& p, SurfaceHit& best) {
  double s = best.s, t = best.t;
  bool stationary = false;
  best.distance_sq =
      newton_to_proven_point(bp, p, 0.0, 1.0, 0.0, 1.0, s, t, best.foot, &best.normal, &stationary);
  best.s = s;
  best.t = t;
  best.u = bp.param_u.to_parent(s);
  best.v = bp.param_v.to_parent(t);
  return stationary;
}

// cos(k pi / PreparedModel::kReachSectors): where sector k of the boundary cone starts.
struct SectorStartCosine {
  double value[PreparedModel::kReachSectors];
  SectorStartCosine() {
    for (int k = 0; k < PreparedModel::kReachSectors; ++k)
      value[k] = std::cos(k * std::numbers::pi / PreparedModel::kReachSectors);
  }
};
const SectorStartCosine kSectorStartCosine;

// The model's reach bounds (PreparedModel::ReachCell) prove that `foot`, a KKT point of
// a Newton over all of `patch` at local (s, t), is the model's closest point to p: p lies
// closer to it than the cut distance of its cell, along the normal (an orthogonal foot) or in the
// normal cone of the surface's edge or corner. A foot on a patch edge inside the surface's domain
// proves nothing: the patch's box may have stopped Newton there (the minimum lies beyond).
bool reach_proves(const PreparedModel& model, std::int64_t patch, double s, double t, const Vec3& p,
                  const Vec3& foot, const Vec3& normal, double distance_sq) {
  const PreparedModel::ReachCell* cell = model.reach_cell(static_cast<std::size_t>(patch), s, t);
  if (cell == nullptr) return false;
  const BezierPatch& bp = model.patch(static_cast<std::size_t>(patch)).patch;
  const NurbsSurface& surface =
      model.model()
          .surfaces[static_cast<std::size_t>(model.patch_surface(static_cast<std::size_t>(patch)))];
  const bool s_edge = s <= 0.0 || s >= 1.0, t_edge = t <= 0.0 || t >= 1.0;
  if (s_edge && !((s <= 0.0 && bp.param_u.lo <= surface.domain_u().lo) ||
                  (s >= 1.0 && bp.param_u.hi >= surface.domain_u().hi))) {
    return false;
  }
  if (t_edge && !((t <= 0.0 && bp.param_v.lo <= surface.domain_v().lo) ||
                  (t >= 1.0 && bp.param_v.hi >= surface.domain_v().hi))) {
    return false;
  }
  if (normal.isZero(0.0)) return false;
  const double along = (p - foot).dot(normal);
  double rho;
  if (s_edge || t_edge) {
    // The direction's angle th from the normal picks the sector: th >= k pi / kReachSectors
    // where cos th <= that angle's cosine (on a sectors' common border either bound holds).
    const double d = std::sqrt(distance_sq);
    const double cos_theta = d > 0.0 ? along / d : 1.0;
    int sector = 0;
    while (sector + 1 < PreparedModel::kReachSectors &&
           cos_theta <= kSectorStartCosine.value[sector + 1])
      ++sector;
    rho = cell->boundary[sector];
  } else {
    rho = along >= 0.0 ? cell->plus : cell->minus;
  }
  return distance_sq < rho * rho;
}

}  // namespace

Projector::Projector(const PreparedModel& model) : model_(model), impl_(std::make_unique<Impl>()) {}

Projector::~Projector() = default;

NURBSREG_HOT_CLONES
void Projector::search_surfaces(const Vec3& p, SurfaceSearch& search, std::int64_t skip_patch,
                                std::int64_t guess_patch, double guess_s, double guess_t,
                                ThreadState& state) const {
  // Hierarchy items: patches first (item_patch maps them), then trim-edge pieces.
  const std::uint32_t patch_items = static_cast<std::uint32_t>(model_.hierarchy_patch_items());
  SurfaceHit& best = search.best;
  OtherItems* others = search.others;
  // One walk, compiled twice: the plain search keeps its small visitor, which the compiler
  // inlines into the walk (in this function's possibly AVX2 code); a visitor with the certifying
  // branches too was left out of line, in default code: 1.4% more instructions, ~6% more time.
  const auto walk = [&](auto certifying) __attribute__((always_inline)) {
    constexpr bool kCertifying = decltype(certifying)::value;
    // The walk's pruning threshold for the best squared distance so far.
    const auto threshold = [others](double best_sq) {
      if constexpr (kCertifying) {
        return others->threshold(best_sq);
      } else {
        return best_sq;
      }
    };
    if constexpr (kCertifying) {
      if (skip_patch >= 0) others->add(skip_patch, best.distance_sq);
    }
    double alpha = threshold(best.distance_sq);
    model_.patch_hierarchy().nearest(
        p, alpha, state.bvh_scratch,
        [this](std::uint32_t k, const Vec3& x) { return model_.item_lower_bound(k, x); },
        [&](std::uint32_t k, double& a) {
          ++state.counters.patches_visited;
          if (k < patch_items) {
            const std::uint32_t patch = model_.item_patch(k);
            state.counters.trimmed_patches_visited += model_.patch_region(patch) != nullptr;
            state.counters.rational_patches_visited += model_.patch(patch).rational;
            if (static_cast<std::int64_t>(patch) == skip_patch) return;
            const bool guessed = static_cast<std::int64_t>(patch) == guess_patch;
            if constexpr (kCertifying) {
              // Clipped against the threshold, not the best: the patch's own minimum, when
              // below it, is wanted even if it does not improve the best.
              SurfaceHit hit;
              hit.distance_sq = a;
              if (!project_onto_patch(model_.patch(patch), p, hit, state.surface_scratch,
                                      &state.surface_stats, guessed ? guess_s : kNaN,
                                      guessed ? guess_t : kNaN, model_.patch_region(patch))) {
                return;
              }
              others->add(patch, hit.distance_sq);
              if (!(hit.distance_sq < best.distance_sq)) return;
              best = hit;
            } else if (!project_onto_patch(model_.patch(patch), p, best, state.surface_scratch,
                                           &state.surface_stats, guessed ? guess_s : kNaN,
                                           guessed ? guess_t : kNaN, model_.patch_region(patch))) {
              return;
            }
            search.surface = model_.patch_surface(patch);
            search.patch = patch;
            search.edge = -1;
            a = threshold(best.distance_sq);
            return;
          }
          // A trim edge of a face (the loops' points, which the trimmed clipping leaves to the
          // edges): the curve projector, exact on the piece.
          const std::size_t e = k - patch_items;
          ++state.counters.edge_pieces_visited;
          CurveHit hit;
          hit.distance_sq = kCertifying ? a : best.distance_sq;
          if (project_onto_piece(model_.edge_piece(e), p, hit, &state.curve_stats)) {
            if constexpr (kCertifying) {
              others->add(-1 - static_cast<std::int64_t>(e), hit.distance_sq);
              if (!(hit.distance_sq < best.distance_sq)) return;
            }
            best.distance_sq = hit.distance_sq;
            best.foot = hit.foot;
            search.surface = model_.edge_piece_info(e).surface;
            search.patch = -1;
            search.edge = static_cast<std::int64_t>(e);
            search.edge_t = hit.u;
            a = threshold(best.distance_sq);
          }
        });
  };
  if (others == nullptr) {
    walk(std::false_type{});
  } else {
    walk(std::true_type{});
  }
}

WarmCertificate Projector::make_certificate(const Vec3& p, const SurfaceHit& best,
                                            std::int64_t patch, std::int64_t edge,
                                            const OtherItems& others, ThreadState& state) const {
  const WarmCertificate tried = tried_at(p);
  // Only a foot on an untrimmed polynomial patch (a foot on a trim edge, or on a patch edge
  // shared with a neighbour, gets no clearance anyway).
  if (patch < 0 || edge >= 0) return tried;
  const std::size_t k = static_cast<std::size_t>(patch);
  if (!model_.surface_certifiable(model_.patch_surface(k))) return tried;
  const double d = std::sqrt(best.distance_sq);
  // The search bounded everything but the answer up to (d + margin)^2 = (d + 2 cap)^2, and a
  // query within radius <= cap of p has its own distance at most d + radius: nothing beyond
  // d + 2 radius is ever needed.
  const double radius_cap = 0.5 * others.margin;
  // A query that moved by m <= radius is proven when its distance (at most d + m) plus m stays
  // within the clearance: a certificate serves moves up to min(radius, (clearance - d) / 2).
  const auto serves = [d](double r, double c) { return std::min(r, 0.5 * (c - d)); };
  double radius = 0.0, clearance = 0.0;
  float box[4] = {0.0f, 1.0f, 0.0f, 1.0f};
  // Keeps the candidate (radius r, clearance c, box N) when it serves more than the kept one.
  const auto keep = [&](double r, double c, float s0, float s1, float t0, float t1) {
    if (!(serves(r, c) > serves(radius, clearance))) return;
    radius = r;
    clearance = c;
    box[0] = s0;
    box[1] = s1;
    box[2] = t0;
    box[3] = t1;
  };
  // N within the foot's patch (certify_patch). The rest of the model: the nearest other item the
  // search met, or the bound over the rest of the patch, or d + 2 radius, whichever is least. It
  // bounds the distance from p to everything outside N from below.
  const auto try_patch = [&] {
    const PatchCertificate local =
        certify_patch(model_.patch(k), p, best.s, best.t, d, radius_cap, state.surface_scratch);
    if (!(local.radius > 0.0)) return;
    const double reach = (d + 2.0 * local.radius) * (d + 2.0 * local.radius);
    const double c = std::sqrt(std::min({reach, local.outside_sq, others.excluding(patch)}));
    keep(local.radius, c, local.s0, local.s1, local.t0, local.t1);
  };
  // N reaching into the neighbours of the foot's patch (certify_span), which then do not limit
  // the clearance. It must hold every surface point that may come within d + 2 radius of p: about
  // the foot, on a surface that curves away no faster than its tangent plane, a disc of radius
  // sqrt((d + 2 cap)^2 - d^2); N is half as wide again, in the patch's local units (|S_s| and
  // |S_t| at the foot). A smaller N (convexity may fail on the first) is tried once.
  const bool spans = model_.surface_c1(model_.patch_surface(k));
  const auto try_span = [&] {
    Vec3 der[6];
    model_.patch(k).patch.derivatives(best.s, best.t, der);
    const double disc = 1.5 * std::sqrt(4.0 * radius_cap * (d + radius_cap));
    const auto half = [disc](const Vec3& tangent) {
      const double length = tangent.norm();
      return length > 0.0 ? std::clamp(disc / length, 0.05, 1.0) : 1.0;
    };
    const double half_s = half(der[1]), half_t = half(der[2]);
    for (const double shrink : {1.0, 0.5}) {
      const SpanCertificate span = certify_span(
          model_, k, p, best.s, best.t, d, radius_cap, shrink * half_s, shrink * half_t,
          std::max(0.0, serves(radius, clearance)), state.surface_scratch);
      if (!(span.radius > 0.0)) continue;
      const double reach = (d + 2.0 * span.radius) * (d + 2.0 * span.radius);
      const double others_sq = others.excluding([&span](std::int64_t id) {
        return std::find(span.patches, span.patches + span.count, id) != span.patches + span.count;
      });
      keep(span.radius, std::sqrt(std::min({reach, span.outside_sq, others_sq})), span.s0, span.s1,
           span.t0, span.t1);
      return;
    }
  };
  // The patch's own box first (cheaper); a spanning one only when that serves less than a
  // sixteenth of the cap (a neighbour, or the patch's own curvature, limits it; the spanning box
  // may serve more). The sixteenth: a certifying frame of the peers benchmark's 49-patch panel
  // then costs 7.5% more than without spanning boxes, against 16% when every certificate short of
  // the cap tries one (the next frame's proven points: 99.94% against 99.97%).
  constexpr double kSpanBelow = 1.0 / 16.0;
  try_patch();
  if (spans && serves(radius, clearance) < kSpanBelow * radius_cap) try_span();
  if (!(radius > 0.0) || !(clearance > d)) return tried;
  // Stored in single precision (WarmCertificate): the rounded anchor is e away from p, so the
  // ball of radius r - e about it lies in the proven one, and everything outside N is at least
  // clearance - e from it; both then rounded down.
  WarmCertificate c;
  c.anchor = p.cast<float>();
  const double e = c.distance_to_anchor(p);
  const auto down = [](double x) {
    float f = static_cast<float>(x);
    if (static_cast<double>(f) > x) f = std::nextafter(f, 0.0f);
    return f;
  };
  c.radius = down(radius - e);
  c.clearance = down(clearance - e);
  if (!(c.radius > 0.0f) || !(static_cast<double>(c.clearance) > d)) return tried;
  ++state.counters.certificates_made;
  c.patch = static_cast<std::int32_t>(patch);
  c.model = model_.serial();
  c.s0 = box[0];
  c.s1 = box[1];
  c.t0 = box[2];
  c.t1 = box[3];
  return c;
}

void Projector::project_range(PointView points, const ProjectionOptions& options,
                              ProjectionResults& out, HintView hints,
                              std::span<const std::uint32_t> order, std::size_t begin,
                              std::size_t end, ThreadState& state) const {
  const Model& model = model_.model();
  const bool surfaces = options.target == ProjectionTarget::surfaces;
  const std::size_t entities = surfaces ? model.surfaces.size() : model.curves.size();
  const double certificate_cap = certificate_radius_cap(options, model_);

  for (std::size_t j = begin; j < end; ++j) {
    const std::size_t i = order.empty() ? j : order[j];
    const Vec3 p = points[i];
    ++state.counters.points;
    if (!p.allFinite()) {
      ++state.counters.skipped;
      write_missing(out, i, ProjectionStatus::skipped_nonfinite);
      clear_certificate(out, i);
      continue;
    }
    if (entities == 0) {
      write_missing(out, i, ProjectionStatus::no_geometry);
      clear_certificate(out, i);
      continue;
    }
    // A copy: the source may be `out` itself (HintView), whose entry i is written below.
    ProjectionHint hint_copy;
    const ProjectionHint* hint = nullptr;
    if (!hints.empty()) {
      hint_copy = hints[i];
      hint = &hint_copy;
    }
    if (surfaces) {
      // Seed alpha with the hint: an upper bound only, so the answer stays exact.
      SurfaceHit best;
      int best_surface = -1;
      std::int64_t best_patch = -1;
      // Warm start: the hint's patch (binary search over the surface's breakpoints) and a
      // box-constrained Newton from the hint on it give a tight upper bound alpha at once, so
      // the BVH walk and the clipping below eliminate almost everything else. The hint only
      // lowers alpha (a true distance) and chooses Newton's start: the answer stays exact.
      std::int64_t hint_patch = -1;
      double hint_s = kNaN, hint_t = kNaN;
      bool hint_certified = false;  // the hinted patch's minimum is already `best`
      bool proven = false;          // `best` is the answer: the hint's certificate proves it
      bool reach_proven = false;    // ... or the model's reach bounds do (then proven too)
      const double limit_sq = options.max_distance * options.max_distance;
      if (valid_hint(hint, entities)) {
        const NurbsSurface& s = model.surfaces[hint->entity];
        const double u = std::clamp(hint->u, s.domain_u().lo, s.domain_u().hi);
        const double v = std::clamp(hint->v, s.domain_v().lo, s.domain_v().hi);
        // A certificate names its patch: no search when (u, v) lies in that patch's box.
        const std::int32_t certified_patch = hint->certificate.patch;
        const auto holds_uv = [&](std::int32_t k) {
          if (k < 0 || static_cast<std::size_t>(k) >= model_.patch_count() ||
              model_.patch_surface(static_cast<std::size_t>(k)) != hint->entity) {
            return false;
          }
          const BezierPatch& bp = model_.patch(static_cast<std::size_t>(k)).patch;
          return u >= bp.param_u.lo && u <= bp.param_u.hi && v >= bp.param_v.lo &&
                 v <= bp.param_v.hi;
        };
        hint_patch =
            holds_uv(certified_patch) ? certified_patch : model_.locate_patch(hint->entity, u, v);
        if (hint_patch >= 0) {
          // The hinted patch; a certificate's Newton may end on a neighbouring one of its box N.
          const BezierPatch* patch_of_hint =
              &model_.patch(static_cast<std::size_t>(hint_patch)).patch;
          const BezierPatch& hinted = *patch_of_hint;
          hint_s = std::clamp(hinted.param_u.to_local(u), 0.0, 1.0);
          hint_t = std::clamp(hinted.param_v.to_local(v), 0.0, 1.0);
          double s_loc = hint_s, t_loc = hint_t;
          bool stationary = false;
          // The Newton ran on the certificate's box N only and proved nothing (p near the
          // ball's rim, or too little clearance): its point still bounds alpha (certificates
          // are made on untrimmed surfaces, so it is a face point) and is where the patch's
          // clipping restarts Newton, which costs less than a second Newton over the whole
          // patch and the patch-wide convexity test below (4-11% fewer instructions per point on
          // the peers benchmark's panels with certificates).
          bool in_box = false;
          // Cheapest: the hint's WarmCertificate covers p. One Newton on its box N proves the
          // answer (see WarmCertificate); otherwise the usual warm start below.
          const WarmCertificate& c = hint->certificate;
          if (c.radius > 0.0 && c.model == model_.serial() && c.patch >= 0 &&
              static_cast<std::size_t>(c.patch) < model_.patch_count()) {
            const double moved = c.distance_to_anchor(p);
            if (moved <= c.radius) {
              // Infinity when the hinted patch is not in N (then the usual warm start below).
              std::int64_t piece_patch = hint_patch;
              const double f =
                  newton_on_certificate_box(model_, c.patch, c.s0, c.s1, c.t0, c.t1, p, piece_patch,
                                            s_loc, t_loc, best.foot, best.normal, stationary);
              if (f < std::numeric_limits<double>::infinity()) {
                best.distance_sq = f;
                hint_patch = piece_patch;
                patch_of_hint = &model_.patch(static_cast<std::size_t>(hint_patch)).patch;
                proven = stationary && best.distance_sq < limit_sq &&
                         std::sqrt(best.distance_sq) + moved <= c.clearance;
                in_box = !proven;
              }
            }
          }
          const BezierPatch& bp = *patch_of_hint;
          if (!proven && !in_box) {
            s_loc = hint_s;
            t_loc = hint_t;
            // Settled at 1e-10 of the patch: the reach bounds prove its point, or the search
            // below starts from it.
            best.distance_sq = newton_to_proven_point(bp, p, 0.0, 1.0, 0.0, 1.0, s_loc, t_loc,
                                                      best.foot, &best.normal, &stationary);
            reach_proven = options.reach_bounds && stationary && best.distance_sq < limit_sq &&
                           reach_proves(model_, hint_patch, s_loc, t_loc, p, best.foot, best.normal,
                                        best.distance_sq);
            proven = reach_proven;
          }
          best.s = s_loc;
          best.t = t_loc;
          best.u = bp.param_u.to_parent(s_loc);
          best.v = bp.param_v.to_parent(t_loc);
          best_surface = hint->entity;
          best_patch = hint_patch;
          // A trimmed face: alpha may only come from a face point. The Newton foot seeds it if
          // it lies in the region; otherwise the patch guess is all the hint gives (it only
          // chooses where the clipping's Newton starts), plus the hint's own point if that one
          // is in the region (a zero-size Newton box evaluates it).
          const TrimRegion* region = model_.surface_region(hint->entity);
          if (proven) {
            // Certificates are made on untrimmed surfaces only: nothing more to check.
          } else if (region == nullptr || region->contains(best.u, best.v)) {
            // The clipping of this patch restarts Newton from the converged point (one step).
            hint_s = s_loc;
            hint_t = t_loc;
            // Cheaper still: when F = |S - p|^2 is provably convex over the whole hinted patch,
            // the KKT point Newton reached is the patch's global minimum (inside the region, for
            // a trimmed face, so also the minimum over the patch's part of the face): the walk
            // below need not clip this patch at all. The same proof as the clipping's convex
            // termination, applied to the patch's own box.
            hint_certified =
                !in_box && stationary &&
                squared_distance_convex(model_.patch(hint_patch), p, state.surface_scratch);
          } else if (region->contains(bp.param_u.to_parent(hint_s), bp.param_v.to_parent(hint_t))) {
            s_loc = hint_s;
            t_loc = hint_t;
            best.distance_sq = newton_on_patch(bp, p, s_loc, s_loc, t_loc, t_loc, s_loc, t_loc,
                                               best.foot, nullptr, &best.normal);
            best.s = s_loc;
            best.t = t_loc;
            best.u = bp.param_u.to_parent(s_loc);
            best.v = bp.param_v.to_parent(t_loc);
          } else {
            best = SurfaceHit{};
            best_surface = -1;
            best_patch = -1;
          }
        }
      }
      if (best.distance_sq >= limit_sq) {
        best = SurfaceHit{};
        best.distance_sq = limit_sq;
        best_surface = -1;
        best_patch = -1;
        hint_certified = false;
        proven = false;
      }
      std::int64_t best_edge = -1;  // the best point is on this trim-edge piece
      double best_edge_t = 0.0;
      // A hint that says a certificate was sought near here and could not be made: none is
      // sought again until the point has moved by the radius cap.
      const bool tried_here = options.certify && hint != nullptr &&
                              hint->certificate.patch == WarmCertificate::kTried &&
                              hint->certificate.distance_to_anchor(p) <= certificate_cap;
      // A point that gets a new certificate: its search also bounds the rest of the model, for
      // the certificate's clearance (a radius of at most the cap needs (d + 2 cap)^2). Only where
      // one can be made: none on a model without an untrimmed polynomial surface, and none for
      // a hint on a trimmed or rational surface, where the answer most likely lies again (such a
      // point is marked as tried instead).
      OtherItems others;
      others.margin = 2.0 * certificate_cap;
      const bool certifying =
          options.certify && !proven && !tried_here && model_.any_certifiable() &&
          (!valid_hint(hint, entities) || model_.surface_certifiable(hint->entity));
      if (!proven) {
        // Cold start: seed alpha with a surface point near p (PreparedModel::seed_from_grid), so
        // the walk prunes from its first step. Only an upper bound: the answer stays exact.
        double seed_sq = -1.0;  // the seed's squared distance when seeded
        if (best_surface < 0 &&
            model_.seed_from_grid(p, limit_sq, best, best_surface, best_patch)) {
          seed_sq = best.distance_sq;
          const PreparedModel::ReachCell* seed_cell =
              model_.reach_cell(static_cast<std::size_t>(best_patch), best.s, best.t);
          // Only where the seed's cell could prove a foot about as far as the seed: elsewhere
          // (small bounds: fine patches, folds) the Newton would mostly be extra work.
          if (options.reach_bounds && seed_cell != nullptr &&
              double(std::max({seed_cell->plus, seed_cell->minus,
                               *std::max_element(std::begin(seed_cell->boundary),
                                                 std::end(seed_cell->boundary))})) >
                  0.5 * std::sqrt(seed_sq)) {
            // A patch with reach bounds: Newton from the seed over the patch, whose KKT point
            // the bounds may prove (no search at all); if not, it is a closer alpha for the
            // search and where the patch's clipping starts.
            const bool stationary = newton_over_patch(
                model_.patch(static_cast<std::size_t>(best_patch)).patch, p, best);
            seed_sq = -1.0;  // polished already
            hint_patch = best_patch;
            hint_s = best.s;
            hint_t = best.t;
            reach_proven = stationary && reach_proves(model_, best_patch, best.s, best.t, p,
                                                      best.foot, best.normal, best.distance_sq);
          }
        }
        SurfaceSearch search{best,      best_surface, best_patch,
                             best_edge, best_edge_t,  certifying ? &others : nullptr};
        if (!reach_proven) {
          search_surfaces(p, search, hint_certified ? hint_patch : -1, hint_patch, hint_s, hint_t,
                          state);
        }
        if (best_edge < 0 && best.distance_sq == seed_sq) {
          // The seed point is the answer (every improvement is strict: nothing was found closer
          // by more than the clipping's accepted 1e-11 R). Polished on its patch as the clipping
          // polishes a corner value, by a descent-only Newton over the whole patch from it (at a
          // stationary point it stays put and only evaluates foot and normal there).
          newton_over_patch(model_.patch(static_cast<std::size_t>(best_patch)).patch, p, best);
        }
      }
      if (best_surface < 0) {
        write_missing(out, i, ProjectionStatus::beyond_max_distance);
        clear_certificate(out, i);
        continue;
      }
      if (reach_proven) {
        ++state.counters.reach_proven;
        // No new certificate (the bounds will prove a nearby point again); a hint's still stands.
        if (options.certify && hint != nullptr && hint->certificate.radius > 0.0) {
          out.certificate[i] = hint->certificate;
        } else {
          clear_certificate(out, i);
        }
      } else if (proven) {
        ++state.counters.certified;
        out.certificate[i] = hint->certificate;
      } else if (options.certify) {
        // make_certificate needs what the certifying search learnt (`others`).
        out.certificate[i] = tried_here ? hint->certificate
                             : certifying
                                 ? make_certificate(p, best, best_patch, best_edge, others, state)
                                 : tried_at(p);
      } else {
        clear_certificate(out, i);
      }
      const NurbsSurface& s = model.surfaces[best_surface];
      if (best_edge >= 0) {
        // An edge point reports its trim curve's (u, v) at the same parameter.
        const Vec2 uv = model_.edge_uv(static_cast<std::size_t>(best_edge), best_edge_t);
        best.u = uv.x();
        best.v = uv.y();
      }
      const double distance = std::sqrt(best.distance_sq);
      // The normal from the Bézier patch that holds the foot (its first derivatives), not via
      // the NURBS surface (span search + basis functions). On a patch edge the NURBS
      // evaluation picks its own side's span, which differs at a C0 crease: there, and where
      // the patch normal is undefined (poles), the surface's own rule decides.
      Vec3 n = Vec3::Zero();
      if (best_patch >= 0) {
        // A patch edge that is the domain's own edge has no neighbour span: the patch decides.
        const BezierPatch& bp = model_.patch(static_cast<std::size_t>(best_patch)).patch;
        const bool inner_s = (best.s > 0.0 || bp.param_u.lo <= s.domain_u().lo) &&
                             (best.s < 1.0 || bp.param_u.hi >= s.domain_u().hi);
        const bool inner_t = (best.t > 0.0 || bp.param_v.lo <= s.domain_v().lo) &&
                             (best.t < 1.0 || bp.param_v.hi >= s.domain_v().hi);
        if (inner_s && inner_t) n = best.normal;
      }
      if (n.isZero(0.0)) n = surface_normal(s, best.u, best.v);
      // A reversed face's outer side is -(S_u x S_v): normal and signed distance follow it.
      if (s.reversed) n = -n;
      write_foot(out, options.foot_sink, i, best.foot, n);
      out.distance[i] = distance;
      out.signed_distance[i] = (p - best.foot).dot(n) < 0.0 ? -distance : distance;
      out.entity[i] = best_surface;
      out.u[i] = best.u;
      out.v[i] = best.v;
      out.on_trim_edge[i] = best_edge >= 0 ? 1 : 0;
    } else {
      CurveHit best;
      int best_curve = -1;
      if (valid_hint(hint, entities)) {
        const NurbsCurve& c = model.curves[hint->entity];
        best.u = std::clamp(hint->u, c.domain().lo, c.domain().hi);
        best.foot = c.evaluate(best.u);
        best.distance_sq = (best.foot - p).squaredNorm();
        best_curve = hint->entity;
      }
      const double limit_sq = options.max_distance * options.max_distance;
      if (best.distance_sq >= limit_sq) {
        best = CurveHit{};
        best.distance_sq = limit_sq;
        best_curve = -1;
      }
      double alpha = best.distance_sq;
      model_.piece_hierarchy().nearest(
          p, alpha, state.bvh_scratch,
          [this](std::uint32_t k, const Vec3& x) { return model_.piece_lower_bound(k, x); },
          [&](std::uint32_t k, double& a) {
            ++state.counters.patches_visited;
            if (project_onto_piece(model_.piece(k), p, best, &state.curve_stats)) {
              best_curve = model_.piece_curve(k);
              a = best.distance_sq;
            }
          });
      if (best_curve < 0) {
        write_missing(out, i, ProjectionStatus::beyond_max_distance);
        clear_certificate(out, i);
        continue;
      }
      const double distance = std::sqrt(best.distance_sq);
      write_foot(out, options.foot_sink, i, best.foot, Vec3::Zero());
      out.distance[i] = distance;
      out.signed_distance[i] = distance;
      out.entity[i] = best_curve;
      out.u[i] = best.u;
      out.v[i] = 0.0;
      out.on_trim_edge[i] = 0;
      clear_certificate(out, i);
    }
    out.status[i] = ProjectionStatus::ok;
  }
}

namespace {
// Checks the hints and sizes the results for a frame: feet and normals unless a FootSink takes
// them, certificates only when the frame can have some (it certifies, or hints carry them).
void prepare_results(PointView points, const ProjectionOptions& options, HintView hints,
                     ProjectionResults& out) {
  if (!hints.empty() && hints.size() != points.size()) {
    throw std::invalid_argument("Projector: " + std::to_string(hints.size()) + " hints for " +
                                std::to_string(points.size()) + " points");
  }
  out.resize(points.size(), !options.foot_sink, options.certify || !hints.empty());
}
}  // namespace

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
  if (options.locality_order && hints.empty() && points.size() >= kLocalityOrderMin &&
      points.size() <= std::numeric_limits<std::uint32_t>::max()) {
    spatial_order(points, impl_->order, impl_->order_scratch);
    order = impl_->order;
  }
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, points.size(), std::max<std::size_t>(1, options.grain)),
      [&](const tbb::blocked_range<std::size_t>& range) {
        project_range(points, options, out, hints, order, range.begin(), range.end(),
                      impl_->states.local());
      });
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
      counters->edge_pieces_visited += s.counters.edge_pieces_visited;
      counters->trimmed_patches_visited += s.counters.trimmed_patches_visited;
      counters->rational_patches_visited += s.counters.rational_patches_visited;
      counters->region_drops += static_cast<std::uint64_t>(s.surface_stats.region_drops);
      counters->region_rejections += static_cast<std::uint64_t>(s.surface_stats.region_rejections);
    }
  }
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
