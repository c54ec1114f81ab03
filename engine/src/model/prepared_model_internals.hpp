#pragma once
// Internal: the parts of PreparedModel that only the engine (and its tests) touch: the oriented
// box of every patch item with the hierarchy walk's lower bound on it, and the cold-start seed
// grid's cells. Include it (it brings model/bvh.hpp) where they are used.

#include <algorithm>

#include "model/bvh.hpp"
#include "nurbsreg/engine/prepared_model.hpp"

namespace nurbsreg::engine {

// A box in the patch's own frame (two tangent directions and the normal of its control net), per
// patch item: much tighter than the axis-aligned box for a tilted or curved patch, so a patch the
// axis-aligned bound lets through is often rejected before its clipping starts. `axis` holds
// orthonormal axes; the patch lies in lo[k] <= axis[k] . x <= hi[k] (convex hull property of the
// control points).
struct PreparedModel::OrientedBox {
  Vec3 axis[3] = {Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
};

// A cell of the seed grid holds a surface point near its centre: a sample of a patch (local
// (s, t) on a kSeedSamples^2 grid, corners included) with its coordinates, or patch -1 (none:
// trimmed surfaces).
struct PreparedModel::SeedCell {
  std::int64_t patch = -1;
  double s = 0, t = 0;
  Vec3 point = Vec3::Zero();
};

inline double PreparedModel::item_lower_bound(std::uint32_t k, const Vec3& p) const {
  // The item's axis-aligned box is not repeated here: the hierarchy walk already takes the larger
  // of this bound and the box distance (Bvh::nearest).
  if (k >= item_oriented_.size()) return item_spheres_[k].squared_distance(p);  // edge piece
  const OrientedBox& ob = item_oriented_[k];
  double oriented = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double y = ob.axis[a].dot(p);
    const double out = std::max(std::max(ob.lo[a] - y, 0.0), y - ob.hi[a]);
    oriented += out * out;
  }
  return oriented;
}

inline double PreparedModel::item_bound(std::uint32_t k, const Vec3& p) const {
  return std::max(item_boxes_[k].squared_distance(p), item_lower_bound(k, p));
}

}  // namespace nurbsreg::engine
