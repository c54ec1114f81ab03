#include "nurbsreg/engine/bvh.hpp"

#include <algorithm>
#include <numeric>

namespace nurbsreg::engine {

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

}  // namespace nurbsreg::engine
