// The search of Projector: one exact best-first walk over the surfaces' hierarchy (patches and
// trim edges), and the WarmCertificate a certifying walk makes possible.

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "platform/cpu_dispatch.hpp"
#include "projection/projector_state.hpp"
#include "proofs/warm_certificate.hpp"

namespace nurbsreg::engine {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// x in single precision, rounded towards zero (a certificate's radius and clearance: stored
// smaller, their claims still hold).
float down_to_float(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) > x) f = std::nextafter(f, 0.0f);
  return f;
}

// The best so far becomes trim-edge piece e's point `hit` (a Projector::SurfaceSearch).
template <class Search>
void take_edge_hit(const PreparedModel& model, Search& search, std::size_t e, const CurveHit& hit) {
  search.best.distance_sq = hit.distance_sq;
  search.best.foot = hit.foot;
  search.surface = model.edge_piece_info(e).surface;
  search.patch = -1;
  search.edge = static_cast<std::int64_t>(e);
  search.edge_t = hit.u;
}

}  // namespace

NURBSREG_HOT_CLONES
void Projector::search_surfaces(const Vec3& p, SurfaceSearch& search, std::int64_t skip_patch,
                                std::int64_t guess_patch, double guess_s, double guess_t,
                                ThreadState& state) const {
  // Hierarchy items: patches first (item_patch maps them), then trim-edge pieces.
  const std::uint32_t patch_items = static_cast<std::uint32_t>(model_.hierarchy_patch_items());
  SurfaceHit& best = search.best;
  OtherItems* others = search.others;
  NearList* list = search.list;
  // One walk, compiled once per kind: the plain search keeps its small visitor, which the
  // compiler inlines into the walk (in this function's possibly AVX2 code); a visitor with the
  // certifying branches too was left out of line, in default code: 1.4% more instructions, ~6%
  // more time.
  enum Kind { kPlain, kCertifyingWalk, kListing };
  const auto walk = [&](auto kind) __attribute__((always_inline)) {
    constexpr bool kCertifying = decltype(kind)::value == kCertifyingWalk;
    constexpr bool kLists = decltype(kind)::value == kListing;
    // The walk's pruning threshold for the best squared distance so far.
    const auto threshold = [others, list](double best_sq) {
      if constexpr (kCertifying) {
        return others->threshold(best_sq);
      } else if constexpr (kLists) {
        return list->threshold(best_sq);
      } else {
        return best_sq;
      }
    };
    // Certifying: could item `id` (its minimum `value`), other than the best so far, be held by
    // a box N about the best's foot? Yes for the best's own patch and the patches of the same
    // surface within OtherItems::span grid steps of it; anything else caps the clearance
    // (OtherItems::cut_sq).
    const auto blocking = [&](std::int64_t id) {
      if (id >= 0 && search.patch >= 0 && search.edge < 0) {
        const std::size_t k = static_cast<std::size_t>(id);
        if (id == search.patch) return false;
        if (model_.patch_surface(k) == search.surface) {
          const PreparedModel::SpanCell a = model_.patch_span(k);
          const PreparedModel::SpanCell b =
              model_.patch_span(static_cast<std::size_t>(search.patch));
          const int reach = others->span;
          if (std::abs(a.a - b.a) <= reach && std::abs(a.b - b.b) <= reach) return false;
        }
      }
      return true;
    };
    // A blocking item caps the clearance; `a` follows.
    const auto note = [&](std::int64_t id, double value, double& a) {
      if constexpr (kCertifying) {
        if (id == OtherItems::kNone || !blocking(id)) return;
        others->cut_sq = std::min(others->cut_sq, value);
        a = threshold(best.distance_sq);
      }
    };
    // The best so far as an item id (OtherItems), or kNone.
    const auto best_item = [&]() -> std::int64_t {
      if (search.edge >= 0) return -1 - search.edge;
      return search.patch >= 0 ? search.patch : OtherItems::kNone;
    };
    if constexpr (kCertifying) {
      if (skip_patch >= 0) others->add(skip_patch, best.distance_sq);
    }
    double alpha = threshold(best.distance_sq);
    model_.patch_hierarchy().nearest(
        p, alpha, state.bvh_scratch,
        [this](std::uint32_t k, const Vec3& x) { return model_.item_lower_bound(k, x); },
        [&](std::uint32_t k, double& a, double bound) {
          if constexpr (kLists) {
            // Listed, and clipped only when it may hold a point nearer than the best.
            if (!list->add(k)) a = threshold(best.distance_sq);
            if (!(bound < best.distance_sq)) return;
          }
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
              if (!(hit.distance_sq < best.distance_sq)) {
                note(patch, hit.distance_sq, a);
                return;
              }
              const std::int64_t previous = best_item();
              const double previous_sq = best.distance_sq;
              best = hit;
              search.surface = model_.patch_surface(patch);
              search.patch = patch;
              search.edge = -1;
              a = threshold(best.distance_sq);
              note(previous, previous_sq, a);
              return;
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
            std::int64_t previous = OtherItems::kNone;
            double previous_sq = 0.0;
            if constexpr (kCertifying) {
              const std::int64_t id = -1 - static_cast<std::int64_t>(e);
              others->add(id, hit.distance_sq);
              if (!(hit.distance_sq < best.distance_sq)) {
                note(id, hit.distance_sq, a);
                return;
              }
              previous = best_item();
              previous_sq = best.distance_sq;
            }
            take_edge_hit(model_, search, e, hit);
            a = threshold(best.distance_sq);
            note(previous, previous_sq, a);
          }
        });
  };
  if (others != nullptr) {
    walk(std::integral_constant<int, kCertifyingWalk>{});
  } else if (list != nullptr) {
    walk(std::integral_constant<int, kListing>{});
    list->finish(best.distance_sq);
    state.counters.lists_made += list->count > 0;
  } else {
    walk(std::integral_constant<int, kPlain>{});
  }
}

NURBSREG_HOT_CLONES
void Projector::search_list(const Vec3& p, SurfaceSearch& search, const NearList& list,
                            std::int64_t guess_patch, double guess_s, double guess_t,
                            ThreadState& state) const {
  const std::uint32_t patch_items = static_cast<std::uint32_t>(model_.hierarchy_patch_items());
  SurfaceHit& best = search.best;
  // The listed items by increasing lower bound (insertion sort: a handful of them); the guessed
  // patch (the previous answer's) first: its clipping starts Newton where that answer was, and
  // the distance it finds prunes most of the others.
  double bound[NearList::kMax];
  std::uint32_t item[NearList::kMax];
  for (int j = 0; j < list.count; ++j) {
    const std::uint32_t listed = list.item[j];
    const double b =
        listed < patch_items && static_cast<std::int64_t>(model_.item_patch(listed)) == guess_patch
            ? -1.0
            : model_.item_bound(listed, p);
    int k = j;
    for (; k > 0 && bound[k - 1] > b; --k) {
      bound[k] = bound[k - 1];
      item[k] = item[k - 1];
    }
    bound[k] = b;
    item[k] = listed;
  }
  for (int j = 0; j < list.count && bound[j] < best.distance_sq; ++j) {
    const std::uint32_t k = item[j];
    ++state.counters.patches_visited;
    if (k < patch_items) {
      const std::uint32_t patch = model_.item_patch(k);
      state.counters.trimmed_patches_visited += model_.patch_region(patch) != nullptr;
      state.counters.rational_patches_visited += model_.patch(patch).rational;
      const bool guessed = static_cast<std::int64_t>(patch) == guess_patch;
      if (project_onto_patch(model_.patch(patch), p, best, state.surface_scratch,
                             &state.surface_stats, guessed ? guess_s : kNaN,
                             guessed ? guess_t : kNaN, model_.patch_region(patch))) {
        search.surface = model_.patch_surface(patch);
        search.patch = patch;
        search.edge = -1;
      }
      continue;
    }
    const std::size_t e = k - patch_items;
    ++state.counters.edge_pieces_visited;
    CurveHit hit;
    hit.distance_sq = best.distance_sq;
    if (project_onto_piece(model_.edge_piece(e), p, hit, &state.curve_stats)) {
      take_edge_hit(model_, search, e, hit);
    }
  }
}

WarmCertificate Projector::make_certificate(const Vec3& p, const SurfaceHit& best,
                                            std::int64_t patch, std::int64_t edge,
                                            const OtherItems& others, ThreadState& state) const {
  const WarmCertificate tried = tried_at(p);
  // Only a foot on a polynomial patch (a foot on a trim edge, or on a patch edge shared with a
  // neighbour, gets no clearance anyway); on a trimmed face, with a box N inside its region.
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
        certify_patch(model_.patch(k), p, best.s, best.t, d, radius_cap, state.surface_scratch,
                      model_.surface_region(model_.patch_surface(k)));
    if (!(local.radius > 0.0)) return;
    const double reach = (d + 2.0 * local.radius) * (d + 2.0 * local.radius);
    const double c =
        std::sqrt(std::min({reach, local.outside_sq, others.excluding(patch), others.cut_sq}));
    keep(local.radius, c, local.s0, local.s1, local.t0, local.t1);
  };
  // N reaching into the neighbours of the foot's patch (certify_span), which then do not limit
  // the clearance. It must hold every surface point that may come within d + 2 radius of p: about
  // the foot, on a surface that curves away no faster than its tangent plane, a disc of radius
  // sqrt((d + 2 cap)^2 - d^2); N is half as wide again, in the patch's local units (|S_s| and
  // |S_t| at the foot), at most OtherItems::span patches beyond P. A smaller N (convexity may
  // fail on the first) is tried once.
  const bool spans = model_.surface_c1(model_.patch_surface(k));
  const auto try_span = [&] {
    Vec3 der[6];
    model_.patch(k).patch.derivatives(best.s, best.t, der);
    const double disc = 1.5 * std::sqrt(4.0 * radius_cap * (d + radius_cap));
    const auto half = [disc, &others](const Vec3& tangent) {
      const double length = tangent.norm();
      return length > 0.0 ? std::clamp(disc / length, 0.05, double(others.span)) : 1.0;
    };
    const double half_s = half(der[1]), half_t = half(der[2]);
    for (const double shrink : {1.0, 0.5}) {
      const SpanCertificate span = certify_span(
          model_, k, p, best.s, best.t, d, radius_cap, shrink * half_s, shrink * half_t,
          std::max(0.0, serves(radius, clearance)), others.span, state.surface_scratch);
      if (!(span.radius > 0.0)) continue;
      const double reach = (d + 2.0 * span.radius) * (d + 2.0 * span.radius);
      const double others_sq = others.excluding([&span](std::int64_t id) {
        return std::find(span.patches, span.patches + span.count, id) != span.patches + span.count;
      });
      keep(span.radius, std::sqrt(std::min({reach, span.outside_sq, others_sq, others.cut_sq})),
           span.s0, span.s1, span.t0, span.t1);
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
  c.radius = down_to_float(radius - e);
  c.clearance = down_to_float(clearance - e);
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

WarmCertificate Projector::make_clearance_certificate(const Vec3& p, const SurfaceHit& best,
                                                      std::int64_t patch, std::int64_t edge,
                                                      const OtherItems& others,
                                                      ThreadState& state) const {
  if (patch < 0 || edge >= 0) return {};
  const double d = std::sqrt(best.distance_sq);
  // Everything but the foot's patch: the nearest other item the walk met, or what it pruned
  // (beyond d + margin, or the cut it pruned at), whichever is least.
  const double reach = (d + others.margin) * (d + others.margin);
  const double clearance = std::sqrt(std::min({reach, others.excluding(patch), others.cut_sq}));
  // Single precision, as make_certificate stores it: the rounded anchor is e away from p.
  WarmCertificate c;
  c.anchor = p.cast<float>();
  const double e = c.distance_to_anchor(p);
  c.clearance = down_to_float(clearance - e);
  if (!(static_cast<double>(c.clearance) > d)) return {};
  c.radius = 0.0f;
  c.patch = static_cast<std::int32_t>(patch);
  c.model = model_.serial();
  ++state.counters.certificates_made;
  return c;
}

}  // namespace nurbsreg::engine
