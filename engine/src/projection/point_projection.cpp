// Projector::project_range: one point at a time, in named steps. Surfaces: input checks, the
// warm start from the hint (its certificate, or a Newton from it that the reach bounds may
// prove, or, on a trimmed face, a face point), the cold-start seed, the exact search, the
// certificate bookkeeping, then the normal and the result writes. Curves: a hint's point, then
// the search over the pieces.

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <numbers>

#include "nurbsreg/engine/sampling.hpp"
#include "projection/projector_state.hpp"
#include "proofs/reach_bounds.hpp"
#include "proofs/warm_certificate.hpp"
#include "surface/patch_newton.hpp"

namespace nurbsreg::engine {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

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
// The size is its trimmed faces' box (geometry_bounds, computed before the parallel loop: see
// Projector::project), not the control points' box: a part whose faces are small pieces of
// large surfaces (linkrods.step: 5.6 against 46.3) would otherwise get radii eight times what
// its own size asks for, whose wider searches serve its moves no better.
double certificate_radius_cap(const ProjectionOptions& options, const PreparedModel& model) {
  if (options.certificate_radius > 0.0) return options.certificate_radius;
  const double size = model.geometry_bounds().box.diagonal();
  return 1e-3 * (size > 0.0 ? size : model.bounds().diagonal());
}

bool valid_hint(const ProjectionHint* hint, std::size_t entities) {
  return hint != nullptr && hint->entity >= 0 &&
         static_cast<std::size_t>(hint->entity) < entities && std::isfinite(hint->u) &&
         std::isfinite(hint->v);
}

// Descent-only Newton over all of patch bp from best's local (s, t); best takes its point (s, t,
// u, v, squared distance, foot, normal). True when it ended at a KKT point of the patch.
bool newton_over_patch(const PreparedPatch& pp, const Vec3& p, SurfaceHit& best) {
  const BezierPatch& bp = pp.patch;
  double s = best.s, t = best.t;
  bool stationary = false;
  best.distance_sq =
      newton_to_proven_point(pp, p, 0.0, 1.0, 0.0, 1.0, s, t, best.foot, &best.normal, &stationary);
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
  const PreparedModel::SurfaceDomain& domain =
      model.surface_domain(model.patch_surface(static_cast<std::size_t>(patch)));
  const bool s_edge = s <= 0.0 || s >= 1.0, t_edge = t <= 0.0 || t >= 1.0;
  if (s_edge &&
      !((s <= 0.0 && bp.param_u.lo <= domain.u.lo) || (s >= 1.0 && bp.param_u.hi >= domain.u.hi))) {
    return false;
  }
  if (t_edge &&
      !((t <= 0.0 && bp.param_v.lo <= domain.v.lo) || (t >= 1.0 && bp.param_v.hi >= domain.v.hi))) {
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

// One point's search state on the surfaces, from the warm start to the result writes.
struct SurfacePoint {
  SurfaceHit best;
  int surface = -1;
  std::int64_t patch = -1;
  std::int64_t edge = -1;  // the best point is on this trim-edge piece (then patch is -1)
  double edge_t = 0.0;
  // The hinted (or seeded) patch and where its clipping restarts Newton; hint_certified: its
  // minimum is already `best` (the search skips it).
  std::int64_t hint_patch = -1;
  double hint_s = kNaN, hint_t = kNaN;
  bool hint_certified = false;
  bool proven = false;        // `best` is the answer: the hint's certificate proves it
  bool reach_proven = false;  // ... or the model's reach bounds do (then proven too)

  // Nothing found yet (alpha = limit_sq): the hint gave no face point within the limit.
  void forget(double limit_sq) {
    best = SurfaceHit{};
    best.distance_sq = limit_sq;
    surface = -1;
    patch = -1;
  }
};

// The patch the hint's (u, v) lies in: the certificate's own patch when it holds (u, v) (no
// search), else PreparedModel::locate_patch; -1 if the surface has none.
std::int64_t hinted_patch(const PreparedModel& model, const ProjectionHint& hint, double u,
                          double v) {
  const std::int32_t k = hint.certificate.patch;
  if (k >= 0 && static_cast<std::size_t>(k) < model.patch_count() &&
      model.patch_surface(static_cast<std::size_t>(k)) == hint.entity) {
    const BezierPatch& bp = model.patch(static_cast<std::size_t>(k)).patch;
    if (u >= bp.param_u.lo && u <= bp.param_u.hi && v >= bp.param_v.lo && v <= bp.param_v.hi) {
      return k;
    }
  }
  return model.locate_patch(hint.entity, u, v);
}

// Cheapest: the hint's WarmCertificate covers p. One Newton on its box N proves the answer (see
// WarmCertificate), or, when it proves nothing (p near the ball's rim, or too little
// clearance), its point still bounds alpha (a certificate's box lies in its face's region, so
// it is a face point) and is where the patch's clipping restarts Newton, which costs less than a
// second Newton over the whole patch and the patch-wide convexity test (4-11% fewer
// instructions per point on the peers benchmark's panels with certificates). Returns whether
// the Newton ran (then `point` has its patch and result); `proven` and `stationary` as it found.
bool newton_on_certificate(const PreparedModel& model, const WarmCertificate& c, const Vec3& p,
                           double limit_sq, SurfacePoint& point, double& s, double& t,
                           bool& stationary) {
  if (!(c.radius > 0.0 && c.model == model.serial() && c.patch >= 0 &&
        static_cast<std::size_t>(c.patch) < model.patch_count())) {
    return false;
  }
  const double moved = c.distance_to_anchor(p);
  if (!(moved <= c.radius)) return false;
  // Infinity when the hinted patch is not in N (then the usual warm start).
  std::int64_t piece_patch = point.hint_patch;
  // A point well away from the certificate's anchor (a new query's first pass borrows its
  // neighbours' certificates): its foot may lie pieces away from the hinted one.
  constexpr double kBorrowed = 0.1;
  const double f = newton_on_certificate_box(model, c.patch, c.s0, c.s1, c.t0, c.t1, p, piece_patch,
                                             s, t, point.best.foot, point.best.normal, stationary,
                                             moved > kBorrowed * c.radius);
  if (!(f < std::numeric_limits<double>::infinity())) return false;
  point.best.distance_sq = f;
  point.hint_patch = piece_patch;
  point.proven = stationary && point.best.distance_sq < limit_sq &&
                 std::sqrt(point.best.distance_sq) + moved <= c.clearance;
  return true;
}

// The warm start: the hint's patch and a box-constrained Newton from the hint on it give a tight
// upper bound alpha at once, so the hierarchy walk and the clipping eliminate almost everything
// else. The hint only lowers alpha (a true distance) and chooses Newton's start: the answer
// stays exact. May prove the answer (the certificate, or the reach bounds after a Newton settled
// at 1e-10 of the patch).
void warm_start(const PreparedModel& model, const ProjectionOptions& options,
                const ProjectionHint& hint, const Vec3& p, double limit_sq, SurfacePoint& point,
                SurfaceScratch& scratch) {
  const PreparedModel::SurfaceDomain& domain = model.surface_domain(hint.entity);
  const double u = std::clamp(hint.u, domain.u.lo, domain.u.hi);
  const double v = std::clamp(hint.v, domain.v.lo, domain.v.hi);
  point.hint_patch = hinted_patch(model, hint, u, v);
  if (point.hint_patch < 0) return;
  {
    const BezierPatch& hinted = model.patch(static_cast<std::size_t>(point.hint_patch)).patch;
    point.hint_s = std::clamp(hinted.param_u.to_local(u), 0.0, 1.0);
    point.hint_t = std::clamp(hinted.param_v.to_local(v), 0.0, 1.0);
  }
  double s_loc = point.hint_s, t_loc = point.hint_t;
  bool stationary = false;
  // The certificate's Newton ran on its box N but proved nothing.
  const bool in_box = newton_on_certificate(model, hint.certificate, p, limit_sq, point, s_loc,
                                            t_loc, stationary) &&
                      !point.proven;
  SurfaceHit& best = point.best;
  // The hinted patch; a certificate's Newton may end on a neighbouring one of its box N.
  const PreparedPatch& hinted = model.patch(static_cast<std::size_t>(point.hint_patch));
  const BezierPatch& bp = hinted.patch;
  if (!point.proven && !in_box) {
    s_loc = point.hint_s;
    t_loc = point.hint_t;
    // Settled at 1e-10 of the patch: the reach bounds prove its point, or the search starts
    // from it.
    best.distance_sq = newton_to_proven_point(hinted, p, 0.0, 1.0, 0.0, 1.0, s_loc, t_loc,
                                              best.foot, &best.normal, &stationary);
    point.reach_proven = options.reach_bounds && stationary && best.distance_sq < limit_sq &&
                         reach_proves(model, point.hint_patch, s_loc, t_loc, p, best.foot,
                                      best.normal, best.distance_sq);
    point.proven = point.reach_proven;
  }
  best.s = s_loc;
  best.t = t_loc;
  best.u = bp.param_u.to_parent(s_loc);
  best.v = bp.param_v.to_parent(t_loc);
  point.surface = hint.entity;
  point.patch = point.hint_patch;
  // A trimmed face: alpha may only come from a face point. The Newton foot seeds it if it lies in
  // the region; otherwise the patch guess is all the hint gives (it only chooses where the
  // clipping's Newton starts), plus the hint's own point if that one is in the region (a
  // zero-size Newton box evaluates it).
  const TrimRegion* region = model.surface_region(hint.entity);
  if (point.proven) {
    // A certificate's box N lies in its face's region (make_certificate): nothing to check.
  } else if (region == nullptr || region->contains(best.u, best.v)) {
    // The clipping of this patch restarts Newton from the converged point (one step).
    point.hint_s = s_loc;
    point.hint_t = t_loc;
    // Cheaper still: when F = |S - p|^2 is provably convex over the whole hinted patch, the KKT
    // point Newton reached is the patch's global minimum (inside the region, for a trimmed face,
    // so also the minimum over the patch's part of the face): the walk need not clip this patch
    // at all. The same proof as the clipping's convex termination, applied to the patch's box.
    point.hint_certified =
        !in_box && stationary && squared_distance_convex(model.patch(point.hint_patch), p, scratch);
  } else if (region->contains(bp.param_u.to_parent(point.hint_s),
                              bp.param_v.to_parent(point.hint_t))) {
    s_loc = point.hint_s;
    t_loc = point.hint_t;
    best.distance_sq = newton_on_patch(bp, p, s_loc, s_loc, t_loc, t_loc, s_loc, t_loc, best.foot,
                                       nullptr, &best.normal);
    best.s = s_loc;
    best.t = t_loc;
    best.u = bp.param_u.to_parent(s_loc);
    best.v = bp.param_v.to_parent(t_loc);
  } else {
    best = SurfaceHit{};
    point.surface = -1;
    point.patch = -1;
  }
}

// The hint's clearance certificate (WarmCertificate::clearance_only), when warm_start's best is
// a point of its patch P: P's own minimum (the Newton's point where F is convex over P, else
// P's clipping from it; on a trimmed face its part of the face, whose trim edges are among the
// items the clearance bounds), then the clearance test. Either way P's minimum is then `best`,
// and the search (if any) skips P.
void prove_by_clearance(const PreparedModel& model, const WarmCertificate& c, const Vec3& p,
                        double limit_sq, SurfacePoint& point, SurfaceScratch& scratch,
                        SurfaceProjectionStats* stats) {
  if (point.proven || !c.clearance_only() || c.model != model.serial() || point.surface < 0 ||
      point.edge >= 0 || point.patch != c.patch ||
      static_cast<std::size_t>(c.patch) >= model.patch_count()) {
    return;
  }
  const std::size_t k = static_cast<std::size_t>(c.patch);
  if (!point.hint_certified) {
    SurfaceHit& best = point.best;
    if (project_onto_patch(model.patch(k), p, best, scratch, stats, point.hint_s, point.hint_t,
                           model.patch_region(k))) {
      point.hint_s = best.s;
      point.hint_t = best.t;
    }
    point.hint_certified = true;
  }
  point.proven = point.best.distance_sq < limit_sq &&
                 std::sqrt(point.best.distance_sq) + c.distance_to_anchor(p) <= c.clearance;
}

// Cold start: seed alpha with a surface point near p (PreparedModel::seed_from_grid), so the walk
// prunes from its first step. Only an upper bound: the answer stays exact. Where the seed's patch
// has reach bounds that could prove a foot about as far as the seed, a Newton from it over the
// patch may prove the answer (no search at all); if not, it is a closer alpha and where the
// patch's clipping starts. Returns the seed's squared distance when it is still an unpolished
// corner sample (-1 otherwise).
double seed_cold_start(const PreparedModel& model, const ProjectionOptions& options, const Vec3& p,
                       double limit_sq, SurfacePoint& point) {
  SurfaceHit& best = point.best;
  if (!model.seed_from_grid(p, limit_sq, best, point.surface, point.patch)) return -1.0;
  const double seed_sq = best.distance_sq;
  const PreparedModel::ReachCell* cell =
      model.reach_cell(static_cast<std::size_t>(point.patch), best.s, best.t);
  // Elsewhere (small bounds: fine patches, folds) the Newton would mostly be extra work. Not on a
  // patch the trim loops cross: a Newton over the whole patch may leave the face.
  if (!(options.reach_bounds && cell != nullptr &&
        model.patch_region(static_cast<std::size_t>(point.patch)) == nullptr &&
        double(
            std::max({cell->plus, cell->minus,
                      *std::max_element(std::begin(cell->boundary), std::end(cell->boundary))})) >
            0.5 * std::sqrt(seed_sq))) {
    return seed_sq;
  }
  const bool stationary =
      newton_over_patch(model.patch(static_cast<std::size_t>(point.patch)), p, best);
  point.hint_patch = point.patch;
  point.hint_s = best.s;
  point.hint_t = best.t;
  point.reach_proven = stationary && reach_proves(model, point.patch, best.s, best.t, p, best.foot,
                                                  best.normal, best.distance_sq);
  return -1.0;  // polished already
}

// The normal at the foot from the Bézier patch that holds it (its first derivatives), not via
// the NURBS surface (span search + basis functions). On a patch edge the NURBS evaluation picks
// its own side's span, which differs at a C0 crease: there, and where the patch normal is
// undefined (poles), the surface's own rule decides. A reversed face's outer side is
// -(S_u x S_v).
Vec3 foot_normal(const PreparedModel& model, const SurfacePoint& point) {
  const SurfaceHit& best = point.best;
  const PreparedModel::SurfaceDomain& domain = model.surface_domain(point.surface);
  Vec3 n = Vec3::Zero();
  if (point.patch >= 0) {
    // A patch edge that is the domain's own edge has no neighbour span: the patch decides.
    const BezierPatch& bp = model.patch(static_cast<std::size_t>(point.patch)).patch;
    const bool inner_s = (best.s > 0.0 || bp.param_u.lo <= domain.u.lo) &&
                         (best.s < 1.0 || bp.param_u.hi >= domain.u.hi);
    const bool inner_t = (best.t > 0.0 || bp.param_v.lo <= domain.v.lo) &&
                         (best.t < 1.0 || bp.param_v.hi >= domain.v.hi);
    if (inner_s && inner_t) n = best.normal;
  }
  if (n.isZero(0.0)) n = surface_normal(model.model().surfaces[point.surface], best.u, best.v);
  if (domain.reversed) n = -n;
  return n;
}

// Does a foot on a trimmed face's patch lie on the face's boundary? The trimmed clipping offers
// any point of the region, and one on the region's edge (a trim loop's vertex, where a patch corner
// or a box-constrained Newton lands) can tie with, or round just below, the edge pieces' exact
// answer, which then never replaces it; a rectangle face (PreparedModel::rectangle_face) has no
// edge pieces at all, its border is its surface's. The answer's distance is the face's minimum,
// and a minimum inside the face is stationary: p - foot along the normal. So an offset clearly
// off the normal (the test ICP's beyond_edge uses too) puts the foot on the boundary. The floor
// keeps Newton's last digits on a point on (or nearly on) the face from counting as off the
// normal.
bool off_normal_on_trimmed_face(const PreparedModel& model, const SurfacePoint& point,
                                const Vec3& p, const Vec3& n) {
  if (point.edge >= 0 || n.isZero(0.0)) return false;
  if (model.surface_region(point.surface) == nullptr && !model.rectangle_face(point.surface)) {
    return false;
  }
  const Vec3 offset = p - point.best.foot;
  const double along = std::abs(offset.dot(n));
  const double distance = offset.norm();
  const double tangential = (offset - offset.dot(n) * n).norm();
  return along < (1.0 - 1e-6) * distance && tangential > 1e-9 * model.bounds().diagonal();
}

// Point i's answer on the surfaces (status is written by the caller).
void write_surface_answer(const PreparedModel& model, const ProjectionOptions& options,
                          const Vec3& p, std::size_t i, SurfacePoint& point,
                          ProjectionResults& out) {
  SurfaceHit& best = point.best;
  if (point.edge >= 0) {
    // An edge point reports its trim curve's (u, v) at the same parameter.
    const Vec2 uv = model.edge_uv(static_cast<std::size_t>(point.edge), point.edge_t);
    best.u = uv.x();
    best.v = uv.y();
  }
  const double distance = std::sqrt(best.distance_sq);
  const Vec3 n = foot_normal(model, point);
  write_foot(out, options.foot_sink, i, best.foot, n);
  out.distance[i] = distance;
  out.signed_distance[i] = (p - best.foot).dot(n) < 0.0 ? -distance : distance;
  out.entity[i] = point.surface;
  out.u[i] = best.u;
  out.v[i] = best.v;
  out.on_trim_edge[i] = point.edge >= 0 || off_normal_on_trimmed_face(model, point, p, n) ? 1 : 0;
}

}  // namespace

// Inlined into project_range, its only caller.
[[gnu::always_inline]] inline ProjectionStatus Projector::project_surface_point(
    const Vec3& p, const ProjectionHint* hint, std::size_t i, const ProjectionOptions& options,
    double certificate_cap, ProjectionResults& out, ThreadState& state) const {
  const std::size_t entities = model_.model().surfaces.size();
  const double limit_sq = options.max_distance * options.max_distance;
  SurfacePoint point;
  if (valid_hint(hint, entities)) {
    warm_start(model_, options, *hint, p, limit_sq, point, state.surface_scratch);
    // Not in a certifying frame: a point its clearance certificate proves would keep it, and
    // each later frame would clip its patch again where a certificate with a box costs one
    // Newton; searched, the point gets one.
    if (!options.certify) {
      prove_by_clearance(model_, hint->certificate, p, limit_sq, point, state.surface_scratch,
                         &state.surface_stats);
    }
  }
  if (point.best.distance_sq >= limit_sq) {
    point.forget(limit_sq);
    point.hint_certified = false;
    point.proven = false;
  }
  // A hint that says a certificate was sought near here and could not be made: none is sought
  // again until the point has moved by the radius cap.
  const bool tried_here = options.certify && hint != nullptr &&
                          hint->certificate.patch == WarmCertificate::kTried &&
                          hint->certificate.distance_to_anchor(p) <= certificate_cap;
  // A point that gets a new certificate: its search also bounds the rest of the model, for the
  // certificate's clearance (a radius of at most the cap needs (d + 2 cap)^2). Only where one
  // can be made: none on a model without an untrimmed polynomial surface, and none for a hint on
  // a rational-only surface, where the answer most likely lies again (such a point is
  // marked as tried instead).
  OtherItems others;
  others.margin = 2.0 * certificate_cap;
  others.span = options.certificate_span;
  // A certificate that could serve moves of less than this share of the cap is not worth
  // making (OtherItems::gives_up).
  constexpr double kGiveUpShare = 1.0 / 32.0;
  others.give_up_margin = 2.0 * kGiveUpShare * certificate_cap;
  // A clearance certificate: its box is the foot's patch alone (every other item caps it), and
  // one that serves moves below a quarter of the radius is not made.
  const bool clearing = options.certify_clearance && !options.certify && !point.proven;
  if (clearing) {
    others.span = 0;
    others.give_up_margin = 0.25 * others.margin;
  }
  const bool certifying =
      clearing || (options.certify && !point.proven && !tried_here && model_.any_certifiable() &&
                   (!valid_hint(hint, entities) || model_.surface_certifiable(hint->entity)));
  // A chained cold frame: the near list of the points before proves this one's answer, or its
  // search makes a new list (ProjectionOptions::chain_cold).
  NearList* listing = nullptr;
  if (state.chain.active() && hint == nullptr && !certifying) {
    NearList& list = state.chain.list;
    if (list.count > 0) {
      SurfaceSearch search{point.best, point.surface, point.patch, point.edge, point.edge_t};
      search_list(p, search, list, state.chain.patch, state.chain.s, state.chain.t, state);
      point.proven = point.surface >= 0 && list.proves(p, point.best.distance_sq);
      if (point.proven) {
        ++list.hits;
        ++state.counters.listed;
      } else {
        state.chain.list_failed();
      }
    }
    if (!point.proven) {
      if (state.chain.skip > 0) {
        --state.chain.skip;
      } else {
        list.start(p, state.chain.margin);
        listing = &list;
      }
      // The list's nearest point (a point of the model) stays the walk's first threshold.
      point.hint_patch = state.chain.patch;
      point.hint_s = state.chain.s;
      point.hint_t = state.chain.t;
    }
  }
  if (!point.proven) {
    const double seed_sq =
        point.surface < 0 ? seed_cold_start(model_, options, p, limit_sq, point) : -1.0;
    SurfaceSearch search{point.best, point.surface, point.patch,
                         point.edge, point.edge_t,  certifying ? &others : nullptr,
                         listing};
    if (!point.reach_proven) {
      search_surfaces(p, search, point.hint_certified ? point.hint_patch : -1, point.hint_patch,
                      point.hint_s, point.hint_t, state);
    } else if (listing != nullptr) {
      listing->count = 0;  // proven without a walk: nothing listed
    }
    // Too many items within the margin (a point far from the model, a crowded corner): the
    // listing walk was wasted, as a list that fails at once.
    if (listing != nullptr && listing->count == 0) state.chain.list_failed();
    if (point.edge < 0 && point.best.distance_sq == seed_sq) {
      // The seed point is the answer (every improvement is strict: nothing was found closer by
      // more than the clipping's accepted 1e-11 R). Polished on its patch as the clipping
      // polishes a corner value, by a descent-only Newton over the whole patch from it (at a
      // stationary point it stays put and only evaluates foot and normal there).
      // On a patch the trim loops cross (a seed inside the face), the polished point (never
      // farther: the Newton only descends) only where it is still inside: otherwise the seed
      // itself, which the clipping found no face point closer than by more than 1e-11 R.
      const std::size_t k = static_cast<std::size_t>(point.patch);
      const TrimRegion* region = model_.patch_region(k);
      SurfaceHit polished = point.best;
      newton_over_patch(model_.patch(k), p, polished);
      if (region == nullptr || region->contains(polished.u, polished.v)) point.best = polished;
    }
  }
  if (state.chain.active()) {
    state.chain.patch = point.edge < 0 ? point.patch : -1;
    state.chain.s = point.best.s;
    state.chain.t = point.best.t;
  }
  if (point.surface < 0) return ProjectionStatus::beyond_max_distance;
  // The certificate that proves the answer, for the next frame's hint.
  if (point.reach_proven) {
    ++state.counters.reach_proven;
    // No new certificate (the bounds will prove a nearby point again); a hint's still stands.
    if (options.certify && hint != nullptr && hint->certificate.radius > 0.0) {
      out.certificate[i] = hint->certificate;
    } else {
      clear_certificate(out, i);
    }
  } else if (point.proven && hint == nullptr) {
    clear_certificate(out, i);  // proven by a near list (chained cold frame)
  } else if (point.proven) {
    ++state.counters.certified;
    out.certificate[i] = hint->certificate;
  } else if (clearing) {
    out.certificate[i] =
        others.gives_up(point.best.distance_sq)
            ? WarmCertificate{}
            : make_clearance_certificate(p, point.best, point.patch, point.edge, others, state);
  } else if (options.certify) {
    // make_certificate needs what the certifying search learnt (`others`).
    out.certificate[i] =
        tried_here ? hint->certificate
        : certifying && !others.gives_up(point.best.distance_sq)
            ? make_certificate(p, point.best, point.patch, point.edge, others, state)
            : tried_at(p);
  } else {
    clear_certificate(out, i);
  }
  write_surface_answer(model_, options, p, i, point, out);
  return ProjectionStatus::ok;
}

// Inlined into project_range, its only caller.
[[gnu::always_inline]] inline ProjectionStatus Projector::project_curve_point(
    const Vec3& p, const ProjectionHint* hint, std::size_t i, const ProjectionOptions& options,
    ProjectionResults& out, ThreadState& state) const {
  const Model& model = model_.model();
  CurveHit best;
  int best_curve = -1;
  if (valid_hint(hint, model.curves.size())) {
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
  if (best_curve < 0) return ProjectionStatus::beyond_max_distance;
  const double distance = std::sqrt(best.distance_sq);
  write_foot(out, options.foot_sink, i, best.foot, Vec3::Zero());
  out.distance[i] = distance;
  out.signed_distance[i] = distance;
  out.entity[i] = best_curve;
  out.u[i] = best.u;
  out.v[i] = 0.0;
  out.on_trim_edge[i] = 0;
  clear_certificate(out, i);
  return ProjectionStatus::ok;
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
    if (state.chain.active() && j % kChainLength == 0) state.chain.reset();
    ProjectionStatus status;
    if (!p.allFinite()) {
      ++state.counters.skipped;
      status = ProjectionStatus::skipped_nonfinite;
    } else if (entities == 0) {
      status = ProjectionStatus::no_geometry;
    } else {
      // A copy: the source may be `out` itself (HintView), whose entry i is written below.
      ProjectionHint hint_copy;
      const ProjectionHint* hint = nullptr;
      if (!hints.empty()) {
        hint_copy = hints[i];
        hint = &hint_copy;
      }
      status = surfaces ? project_surface_point(p, hint, i, options, certificate_cap, out, state)
                        : project_curve_point(p, hint, i, options, out, state);
    }
    if (status == ProjectionStatus::ok) {
      out.status[i] = status;
    } else {
      write_missing(out, i, status);
      clear_certificate(out, i);
    }
  }
}

}  // namespace nurbsreg::engine
