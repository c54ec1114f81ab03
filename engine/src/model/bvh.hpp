#pragma once
// A bounding volume hierarchy over axis-aligned boxes (Bézier patches or curve pieces of a whole
// model) and an exact best-first nearest search on it.
//
// Built once, immutable, const and thread-safe to query. The search visits primitives in order of
// increasing lower-bound distance and stops as soon as the lower bound of what is left cannot
// beat alpha, the best squared distance found so far; the caller's visit function refines alpha
// exactly (e.g. by spherical clipping), so the answer is exact whatever the tree's quality.
//
// Two forms of the same tree: the binary tree of the top-down build (nodes(), order(): for
// inspection and tests) and, for the queries, the same tree collapsed into 4-wide nodes whose
// children's boxes are stored as structure of arrays, so one node's four box distances are one
// vectorisable pass and a query touches about half as many nodes.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <span>
#include <type_traits>
#include <vector>

#include "nurbsreg/engine/bounds.hpp"

namespace nurbsreg::engine {

class Bvh {
 public:
  struct Node {
    Aabb box;
    // Leaf: primitives order_[first, first + count); inner: children at `first` and `first + 1`
    // (count == 0).
    std::uint32_t first = 0;
    std::uint32_t count = 0;
  };

  // Four child slots. Slot k's box is (lo_x[k], lo_y[k], lo_z[k]) - (hi_x[k], hi_y[k], hi_z[k]);
  // child[k] >= 0 is a wide node, child[k] < 0 the primitive ~child[k], and an unused slot has
  // an empty box (lo = +inf, hi = -inf: its distance is +inf, so it is never entered).
  struct alignas(64) WideNode {
    static constexpr int kWidth = 4;
    double lo_x[kWidth], lo_y[kWidth], lo_z[kWidth];
    double hi_x[kWidth], hi_y[kWidth], hi_z[kWidth];
    std::int32_t child[kWidth];
  };

  // Per-thread working memory for queries; reused across queries, it grows once to the tree's
  // size and then never allocates.
  struct Scratch {
    struct Entry {
      double bound;
      std::int32_t ref;  // as WideNode::child
    };
    // The search frontier (Bvh::nearest): its sorted near part, then its unsorted far part.
    std::vector<Entry> heap;
  };

  Bvh() = default;
  // `boxes[i]` bounds primitive i. `leaf_size` primitives at most per leaf of the binary tree.
  explicit Bvh(std::span<const Aabb> boxes, int leaf_size = 2);

  bool empty() const { return nodes_.empty(); }
  std::span<const Node> nodes() const { return nodes_; }
  // Primitive indices in leaf order.
  std::span<const std::uint32_t> order() const { return order_; }
  // The query form: wide_nodes()[0] is the root (empty when the tree is).
  std::span<const WideNode> wide_nodes() const { return wide_; }

  // Best-first search. `lower_bound(primitive, p)` returns a squared-distance lower bound for a
  // primitive (the larger of it and the primitive's box distance is used); `visit(primitive,
  // alpha_sq)` (or `visit(primitive, alpha_sq, bound)`, told that bound) may lower alpha_sq.
  // Primitives are visited in order of increasing bound, and one whose bound is >= alpha_sq at that
  // moment is never visited. Always inlined: the walk then runs in its caller's code, which may be
  // an AVX2 clone (engine/src/platform/cpu_dispatch.hpp).
  template <typename LowerBound, typename Visit>
  void nearest(const Vec3& p, double& alpha_sq, Scratch& scratch, LowerBound&& lower_bound,
               Visit&& visit) const;

  // The primitive reached by descending from the root into the child with the nearest box at
  // every level (no backtracking): a cheap guess of a primitive near p, e.g. to seed alpha with
  // an upper bound before nearest(). -1 for an empty tree.
  std::int64_t greedy_primitive(const Vec3& p) const;

 private:
  void build(std::span<const Aabb> boxes, std::span<const Vec3> centers, std::uint32_t node,
             std::uint32_t first, std::uint32_t count, int leaf_size);
  struct Candidate;
  std::int32_t collapse(std::span<const Aabb> boxes, const Candidate& top);

  std::vector<Node> nodes_;
  std::vector<std::uint32_t> order_;
  std::vector<WideNode> wide_;
};

namespace bvh_detail {

// Squared distances from p to the four boxes of a wide node, as Aabb::squared_distance computes
// each (per axis max(lo - p, 0, p - hi), then x^2 + y^2 + z^2): loops over the four slots that
// the compiler vectorises.
[[gnu::always_inline]] inline void box_distances(const Bvh::WideNode& node, const Vec3& p,
                                                 double* out) {
  constexpr int W = Bvh::WideNode::kWidth;
  const double px = p.x(), py = p.y(), pz = p.z();
  double dx[W], dy[W], dz[W];
  for (int k = 0; k < W; ++k) {
    const double a = node.lo_x[k] - px, b = px - node.hi_x[k];
    dx[k] = std::max(std::max(a, 0.0), b);
  }
  for (int k = 0; k < W; ++k) {
    const double a = node.lo_y[k] - py, b = py - node.hi_y[k];
    dy[k] = std::max(std::max(a, 0.0), b);
  }
  for (int k = 0; k < W; ++k) {
    const double a = node.lo_z[k] - pz, b = pz - node.hi_z[k];
    dz[k] = std::max(std::max(a, 0.0), b);
  }
  for (int k = 0; k < W; ++k)
    out[k] = dx[k] * dx[k] + dy[k] * dy[k] + dz[k] * dz[k];
}

}  // namespace bvh_detail

inline std::int64_t Bvh::greedy_primitive(const Vec3& p) const {
  if (wide_.empty()) return -1;
  std::int32_t ref = 0;
  double distance[WideNode::kWidth];
  for (;;) {
    const WideNode& node = wide_[static_cast<std::size_t>(ref)];
    bvh_detail::box_distances(node, p, distance);
    int pick = 0;
    for (int k = 1; k < WideNode::kWidth; ++k) {
      if (distance[k] < distance[pick]) pick = k;
    }
    const std::int32_t child = node.child[pick];
    if (child < 0) return static_cast<std::int64_t>(~child);
    ref = child;
  }
}

template <typename LowerBound, typename Visit>
[[gnu::always_inline]] inline void Bvh::nearest(const Vec3& p, double& alpha_sq, Scratch& scratch,
                                                LowerBound&& lower_bound, Visit&& visit) const {
  if (wide_.empty()) return;
  // Every entry ever inserted is one slot of one wide node (plus the root): this bounds each part
  // of the frontier, so after the first query on a tree it never reallocates.
  const std::size_t capacity = Bvh::WideNode::kWidth * wide_.size() + 1;
  if (scratch.heap.size() < 3 * capacity) scratch.heap.resize(3 * capacity);
  // The frontier in two parts, popped in the order of one sorted frontier (increasing bound,
  // the last inserted first among equal bounds):
  // - the near part: entries below `split`, sorted by increasing bound in [head, tail) of the
  //   buffer's first 2 capacity slots and popped at the head. Many entries of a point near the
  //   model have bound 0 (their box holds the point): they go in at the head, the rest is placed
  //   by a scan from the tail;
  // - the far part: entries at or above `split`, as they came. Near the model most of them are
  //   boxes the first threshold's ball only grazes, never needed once the first items visited
  //   lower alpha; sorted in at once, each would shift past the whole near part. When the near
  //   part runs dry, those still below alpha are sorted in, in the order they came.
  Scratch::Entry* const buffer = scratch.heap.data();
  Scratch::Entry* const far = buffer + 2 * capacity;
  std::size_t head = capacity, tail = capacity, far_size = 0;
  // A quarter of the first threshold: the walk's instruction count on the real parts varies
  // little with it (bench/README.md).
  constexpr double kSplitShare = 0.25;
  double split = kSplitShare * alpha_sq;
  auto insert_near = [&](double bound, std::int32_t ref) {
    if (head == tail || !(buffer[head].bound < bound)) {
      buffer[--head] = {bound, ref};
      return;
    }
    std::size_t k = tail++;
    while (buffer[k - 1].bound >= bound) {  // stops at head at the latest
      buffer[k] = buffer[k - 1];
      --k;
    }
    buffer[k] = {bound, ref};
  };
  auto insert = [&](double bound, std::int32_t ref) {
    if (bound < split) {
      insert_near(bound, ref);
    } else {
      far[far_size++] = {bound, ref};
    }
  };
  insert(nodes_[0].box.squared_distance(p), 0);
  double distance[Bvh::WideNode::kWidth];
  for (;;) {
    if (head == tail) {
      // Every far entry is at least `split`; those at or above alpha are never needed (alpha only
      // falls), and every later entry is below alpha: all of it goes to the near part now.
      for (std::size_t j = 0; j < far_size; ++j) {
        if (far[j].bound < alpha_sq) insert_near(far[j].bound, far[j].ref);
      }
      far_size = 0;
      split = std::numeric_limits<double>::infinity();
      if (head == tail) break;
    }
    const Scratch::Entry entry = buffer[head++];
    if (entry.bound >= alpha_sq) break;  // everything left is at least as far
    if (entry.ref < 0) {
      // A visitor may also take the primitive's bound (a listing walk records the primitives
      // between the best and its threshold without clipping them).
      if constexpr (std::is_invocable_v<Visit&, std::uint32_t, double&, double>) {
        visit(static_cast<std::uint32_t>(~entry.ref), alpha_sq, entry.bound);
      } else {
        visit(static_cast<std::uint32_t>(~entry.ref), alpha_sq);
      }
      continue;
    }
    const WideNode& node = wide_[static_cast<std::size_t>(entry.ref)];
    bvh_detail::box_distances(node, p, distance);
    for (int k = 0; k < WideNode::kWidth; ++k) {
      double bound = distance[k];
      if (!(bound < alpha_sq)) continue;
      const std::int32_t child = node.child[k];
      if (child < 0) {
        // A primitive: its own (tighter) bound orders and prunes it.
        bound = std::max(bound, lower_bound(static_cast<std::uint32_t>(~child), p));
        if (!(bound < alpha_sq)) continue;
      }
      insert(bound, child);
    }
  }
}

}  // namespace nurbsreg::engine
