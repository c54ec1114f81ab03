#pragma once
// A bounding volume hierarchy over axis-aligned boxes (Bézier patches or curve pieces of a whole
// model) and an exact best-first nearest search on it.
//
// Built once, immutable, const and thread-safe to query. The search visits primitives in order of
// increasing lower-bound distance and stops as soon as the lower bound of what is left cannot
// beat alpha, the best squared distance found so far; the caller's visit function refines alpha
// exactly (e.g. by spherical clipping), so the answer is exact whatever the tree's quality.

#include <algorithm>
#include <cstdint>
#include <span>
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

  // Per-thread working memory for queries; reused across queries, it grows once to the tree's
  // depth-bounded size and then never allocates.
  struct Scratch {
    struct Entry {
      double bound;
      std::uint32_t node;
    };
    std::vector<Entry> heap;
  };

  Bvh() = default;
  // `boxes[i]` bounds primitive i. `leaf_size` primitives at most per leaf.
  explicit Bvh(std::span<const Aabb> boxes, int leaf_size = 2);

  bool empty() const { return nodes_.empty(); }
  std::span<const Node> nodes() const { return nodes_; }
  // Primitive indices in leaf order.
  std::span<const std::uint32_t> order() const { return order_; }

  // Best-first search. `lower_bound(primitive, p)` returns a squared-distance lower bound for a
  // primitive (at least the box distance is used for nodes); `visit(primitive, alpha_sq)` may
  // lower alpha_sq. Primitives whose lower bound is >= alpha_sq are never visited.
  template <typename LowerBound, typename Visit>
  void nearest(const Vec3& p, double& alpha_sq, Scratch& scratch, LowerBound&& lower_bound,
               Visit&& visit) const;

 private:
  void build(std::span<const Aabb> boxes, std::span<const Vec3> centers, std::uint32_t node,
             std::uint32_t first, std::uint32_t count, int leaf_size);

  std::vector<Node> nodes_;
  std::vector<std::uint32_t> order_;
};

template <typename LowerBound, typename Visit>
void Bvh::nearest(const Vec3& p, double& alpha_sq, Scratch& scratch, LowerBound&& lower_bound,
                  Visit&& visit) const {
  if (nodes_.empty()) return;
  auto& heap = scratch.heap;
  heap.clear();
  // Min-heap on bound.
  auto greater = [](const Scratch::Entry& a, const Scratch::Entry& b) { return a.bound > b.bound; };
  heap.push_back({nodes_[0].box.squared_distance(p), 0});
  while (!heap.empty()) {
    std::pop_heap(heap.begin(), heap.end(), greater);
    const Scratch::Entry entry = heap.back();
    heap.pop_back();
    if (entry.bound >= alpha_sq) break;  // everything left is at least as far
    const Node& node = nodes_[entry.node];
    if (node.count > 0) {
      for (std::uint32_t k = node.first; k < node.first + node.count; ++k) {
        const std::uint32_t primitive = order_[k];
        if (lower_bound(primitive, p) < alpha_sq) visit(primitive, alpha_sq);
      }
      continue;
    }
    for (std::uint32_t child = node.first; child < node.first + 2; ++child) {
      const double bound = nodes_[child].box.squared_distance(p);
      if (bound < alpha_sq) {
        heap.push_back({bound, child});
        std::push_heap(heap.begin(), heap.end(), greater);
      }
    }
  }
}

}  // namespace nurbsreg::engine
