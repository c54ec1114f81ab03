#pragma once
// Internal: what the parts of Projector (projection.cpp: frames; surface_search.cpp: the search
// and the certificates it makes; point_projection.cpp: one point's steps) share: the per-thread
// state, the frame-wide state and what a certifying search learns of the other items.

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "model/prepared_model_internals.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/spatial_order.hpp"

namespace nurbsreg::engine {

// What a listing search (ProjectionOptions::chain_cold) learns at its point `anchor`: every
// hierarchy item that could lie within `clearance` of it is one of `item` (the walk pruned
// everything else at its final threshold (d + margin)^2, d its answer's distance, or above it).
// A later query q whose closest point among the listed items is at distance d_q with
// d_q + |q - anchor| <= clearance has the model's closest point there: every other item is at
// least clearance - |q - anchor| >= d_q from q. Listing stops (count = 0: no list) when more
// items than kMax lie within the threshold, where a list would cost about as much as the walk.
struct Projector::NearList {
  static constexpr int kMax = 16;
  Vec3 anchor = Vec3::Zero();
  double margin = 0.0;
  double clearance = 0.0;
  int count = 0;
  int hits = 0;  // answers it proved
  bool overflowed = false;
  std::uint32_t item[kMax];

  // The walk's threshold for the best squared distance so far.
  double threshold(double best_sq) const {
    if (overflowed) return best_sq;
    const double d = std::sqrt(best_sq) + margin;
    return d * d;
  }
  // Records item k (visited in order of its bound); false once the list is full.
  bool add(std::uint32_t k) {
    if (overflowed) return false;
    if (count == kMax) {
      overflowed = true;
      return false;
    }
    item[count++] = k;
    return true;
  }
  void start(const Vec3& p, double list_margin) {
    anchor = p;
    margin = list_margin;
    clearance = 0.0;
    count = 0;
    hits = 0;
    overflowed = false;
  }
  // After the walk: the list stands when it holds everything within (d + margin)^2. The
  // clearance is shrunk by a few units in the last place for the rounding of the bounds and of
  // the square root.
  void finish(double best_sq) {
    if (overflowed || !(best_sq < std::numeric_limits<double>::infinity())) {
      count = 0;
      return;
    }
    clearance = (std::sqrt(best_sq) + margin) * (1.0 - 1e-12);
  }
  // Does the list prove an answer at distance sqrt(best_sq) for query q?
  bool proves(const Vec3& q, double best_sq) const {
    return count > 0 && std::sqrt(best_sq) + (q - anchor).norm() <= clearance;
  }
};

struct Projector::ThreadState {
  SurfaceScratch surface_scratch;
  SurfaceProjectionStats surface_stats;
  CurveProjectionStats curve_stats;
  Bvh::Scratch bvh_scratch;
  ProjectionCounters counters;
  // A block of a frame in locality order, projected here in sequence and then put in place
  // (Projector::project).
  std::vector<Vec3> staged_points;
  ProjectionResults staged;
  // A chained cold frame (ProjectionOptions::chain_cold) as this thread walks it: the near list
  // of the chain so far and the previous point's answer (where the next clipping of its patch
  // starts Newton).
  struct Chain {
    NearList list;
    double margin = 0.0;  // > 0 while the frame chains
    std::int64_t patch = -1;
    double s = 0.0, t = 0.0;
    // Where lists do not pay (sparse points, noise beyond the margin: a list fails at the next
    // point), the next `skip` points walk without making one; each list that proved nothing
    // doubles that pause, one that did ends it.
    int skip = 0, pause = 0;

    bool active() const { return margin > 0.0; }
    void reset() {
      list.count = 0;
      patch = -1;
      skip = 0;
      pause = 0;
    }
    // The list failed at a point: pause listing if it proved nothing.
    void list_failed() {
      constexpr int kLongestPause = 64;
      pause = list.hits == 0 ? std::clamp(2 * pause, 1, kLongestPause) : 0;
      skip = pause;
      list.count = 0;
    }
  };
  Chain chain;
};

struct Projector::Impl {
  tbb::enumerable_thread_specific<ThreadState> states;
  // The frame's processing order (ProjectionOptions::locality_order), reused across frames.
  FrameVector<std::uint32_t> order;
  SpatialOrderScratch order_scratch;
};

// What a certifying search learns of the items other than its answer, so that the certificate
// needs no second search: the walk prunes at (d + margin)^2 (or cut_sq) instead of d^2 (d: the best
// distance so far) and clips each item it visits against that threshold, so every item ends up
// either with its exact minimum recorded or proven at least (d_final + margin)^2 away (pruned, or
// clipped without a point below the threshold, which never falls below the final one). Kept:
// the kSlots smallest minima of distinct items (patch index, or -1 - edge piece), enough for "the
// nearest item other than those of a certificate's box N" (N spans up to 3 x 3 patches at the
// default span; with more, slots full of N's patches leave the last one's minimum as the bound).
struct Projector::OtherItems {
  static constexpr std::int64_t kNone = std::numeric_limits<std::int64_t>::min();
  static constexpr int kSlots = 12;
  double margin = 0.0;
  // ProjectionOptions::certificate_span: a patch of the best's surface within this many grid
  // steps of the best's patch may lie in a box N about its foot (it does not cap the clearance).
  int span = 1;
  // The cheap failure path: an item that no box N about the best can hold (another face, an
  // edge, a patch beyond the best's neighbours) caps every certificate's clearance at its minimum
  // (cut_sq): the walk prunes there from then on, and the clearance is at most sqrt(cut_sq), since
  // items pruned against it are known only to be beyond it. When that cap ends within
  // `give_up_margin` of the final best distance (thin walls, close sheets, a foot by another
  // face), a certificate would serve moves below half of it: none is made (gives_up; only a
  // matter of cost, the answer is the search's). Judged against the final best, not the best at
  // the time: early in a walk the best may be a far face's trim edge, and two pieces of that edge
  // meeting at their minimum are "close" to it, while the answer later lies far nearer.
  double give_up_margin = 0.0;
  double cut_sq = std::numeric_limits<double>::infinity();
  // Ascending by minimum; unused slots at the end (kNone, infinity).
  std::int64_t item[kSlots];
  double minimum[kSlots];

  OtherItems() {
    std::fill(std::begin(item), std::end(item), kNone);
    std::fill(std::begin(minimum), std::end(minimum), std::numeric_limits<double>::infinity());
  }
  double threshold(double best_sq) const {
    const double d = std::sqrt(best_sq) + margin;
    return std::min(d * d, std::max(cut_sq, best_sq));
  }
  bool gives_up(double best_sq) const {
    const double d = std::sqrt(best_sq) + give_up_margin;
    return cut_sq < d * d;
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

// The mark of a point for which no certificate could be made (WarmCertificate::kTried).
inline WarmCertificate tried_at(const Vec3& p) {
  WarmCertificate tried;
  tried.anchor = p.cast<float>();
  tried.patch = WarmCertificate::kTried;
  return tried;
}

}  // namespace nurbsreg::engine
