#include "model/bvh.hpp"

#include <algorithm>
#include <limits>
#include <numeric>

namespace nurbsreg::engine {

// A subtree of the binary tree while it is collapsed: an inner node, or a run of primitives
// order_[first, first + count) (a leaf, or half of one: leaves of several primitives are split
// further so that every wide slot holds one primitive or one wide node).
struct Bvh::Candidate {
  Aabb box;
  bool inner = false;
  std::uint32_t node = 0;              // inner: binary node
  std::uint32_t first = 0, count = 0;  // run

  static Candidate of_node(const Bvh& bvh, std::uint32_t index) {
    const Node& n = bvh.nodes_[index];
    Candidate c;
    c.box = n.box;
    c.inner = n.count == 0;
    c.node = index;
    c.first = n.first;
    c.count = n.count;
    return c;
  }
  static Candidate of_run(std::span<const Aabb> boxes, std::span<const std::uint32_t> order,
                          std::uint32_t first, std::uint32_t count) {
    Candidate c;
    for (std::uint32_t k = first; k < first + count; ++k)
      c.box.extend(boxes[order[k]]);
    c.first = first;
    c.count = count;
    return c;
  }
  bool splittable() const { return inner || count > 1; }
  // Half the surface area: the subtree most likely to be entered is opened first.
  double area() const {
    if (box.empty()) return 0.0;
    const Vec3 e = box.hi - box.lo;
    return e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
  }
};

Bvh::Bvh(std::span<const Aabb> boxes, int leaf_size) {
  if (boxes.empty()) return;
  order_.resize(boxes.size());
  std::iota(order_.begin(), order_.end(), 0u);
  std::vector<Vec3> centers(boxes.size());
  for (std::size_t i = 0; i < boxes.size(); ++i)
    centers[i] = boxes[i].center();
  nodes_.reserve(2 * boxes.size());
  nodes_.emplace_back();
  build(boxes, centers, 0, 0, static_cast<std::uint32_t>(boxes.size()), std::max(1, leaf_size));
  // About n / 3 wide nodes for n primitives.
  wide_.reserve(boxes.size() / 2 + 1);
  collapse(boxes, Candidate::of_node(*this, 0));
}

// Top-down median split on the longest axis of the centres' box: deterministic, O(n log^2 n),
// and good enough because the search is exact regardless of tree quality.
void Bvh::build(std::span<const Aabb> boxes, std::span<const Vec3> centers, std::uint32_t node,
                std::uint32_t first, std::uint32_t count, int leaf_size) {
  Aabb box;
  Aabb center_box;
  for (std::uint32_t k = first; k < first + count; ++k) {
    box.extend(boxes[order_[k]]);
    center_box.extend(centers[order_[k]]);
  }
  nodes_[node].box = box;
  if (count <= static_cast<std::uint32_t>(leaf_size)) {
    nodes_[node].first = first;
    nodes_[node].count = count;
    return;
  }
  int axis = 0;
  const Vec3 extent = center_box.hi - center_box.lo;
  if (extent.y() > extent[axis]) axis = 1;
  if (extent.z() > extent[axis]) axis = 2;
  const std::uint32_t half = count / 2;
  std::nth_element(order_.begin() + first, order_.begin() + first + half,
                   order_.begin() + first + count, [&](std::uint32_t a, std::uint32_t b) {
                     // Ties broken by index: the tree must not depend on the library's sort.
                     if (centers[a][axis] != centers[b][axis]) {
                       return centers[a][axis] < centers[b][axis];
                     }
                     return a < b;
                   });
  // Children side by side, so an inner node stores one index.
  const auto left = static_cast<std::uint32_t>(nodes_.size());
  nodes_.emplace_back();
  nodes_.emplace_back();
  nodes_[node].first = left;
  nodes_[node].count = 0;
  build(boxes, centers, left, first, half, leaf_size);
  build(boxes, centers, left + 1, first + half, count - half, leaf_size);
}

// Collapses the binary subtree `top` into wide nodes (pre-order, so the root is wide_[0]):
// the node's slots are `top`'s descendants, opened largest first until there are four, and each
// slot that is not a single primitive becomes a wide node of its own.
std::int32_t Bvh::collapse(std::span<const Aabb> boxes, const Candidate& top) {
  const auto index = static_cast<std::int32_t>(wide_.size());
  wide_.emplace_back();
  auto split = [&](const Candidate& c, Candidate& a, Candidate& b) {
    if (c.inner) {
      a = Candidate::of_node(*this, nodes_[c.node].first);
      b = Candidate::of_node(*this, nodes_[c.node].first + 1);
    } else {
      const std::uint32_t half = c.count / 2;
      a = Candidate::of_run(boxes, order_, c.first, half);
      b = Candidate::of_run(boxes, order_, c.first + half, c.count - half);
    }
  };
  Candidate slots[WideNode::kWidth];
  int used = 1;
  slots[0] = top;
  while (used < WideNode::kWidth) {
    int widest = -1;
    for (int k = 0; k < used; ++k) {
      if (slots[k].splittable() && (widest < 0 || slots[k].area() > slots[widest].area())) {
        widest = k;
      }
    }
    if (widest < 0) break;
    const Candidate c = slots[widest];
    split(c, slots[widest], slots[used]);
    ++used;
  }
  std::int32_t children[WideNode::kWidth];
  for (int k = 0; k < WideNode::kWidth; ++k) {
    if (k >= used) {
      children[k] = -1;  // unused: its empty box keeps it out of every search
    } else if (!slots[k].splittable()) {
      children[k] = ~static_cast<std::int32_t>(order_[slots[k].first]);
    } else {
      children[k] = collapse(boxes, slots[k]);
    }
  }
  WideNode& w = wide_[static_cast<std::size_t>(index)];  // after the recursion's emplace_backs
  const double inf = std::numeric_limits<double>::infinity();
  for (int k = 0; k < WideNode::kWidth; ++k) {
    const bool live = k < used;
    const Aabb& b = slots[k].box;
    w.lo_x[k] = live ? b.lo.x() : inf;
    w.lo_y[k] = live ? b.lo.y() : inf;
    w.lo_z[k] = live ? b.lo.z() : inf;
    w.hi_x[k] = live ? b.hi.x() : -inf;
    w.hi_y[k] = live ? b.hi.y() : -inf;
    w.hi_z[k] = live ? b.hi.z() : -inf;
    w.child[k] = children[k];
  }
  return index;
}

}  // namespace nurbsreg::engine
