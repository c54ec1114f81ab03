#pragma once
// Internal to registration: a uniform grid over 3-D points for fixed-radius neighbour queries
// and voxel downsampling (the coarse stage's clouds are roughly uniform in density: voxelised
// scans and voxelised area-uniform model samples, so a grid with the query radius as its cell
// is as fast as a tree and much simpler). Built once (allocates), then const: queries from any
// number of threads. Cells are kept in key order, so every result is deterministic.

#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::registration::detail {

class PointGrid {
 public:
  PointGrid() = default;
  // `points` must outlive the grid; cell > 0.
  PointGrid(std::span<const engine::Vec3> points, double cell);

  // Calls f(index, squared distance) for every point within `radius` (<= cell) of q, in a
  // deterministic order (cell by cell, points in index order within a cell).
  template <class F>
  void for_each_within(const engine::Vec3& q, double radius, const F& f) const {
    const double r2 = radius * radius;
    const Key c = key_of(q);
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        for (std::int64_t dz = -1; dz <= 1; ++dz) {
          const auto it = cells_.find(pack(c.x + dx, c.y + dy, c.z + dz));
          if (it == cells_.end()) continue;
          for (std::uint32_t k = it->second.begin; k < it->second.end; ++k) {
            const std::uint32_t i = order_[k];
            const double d2 = (points_[i] - q).squaredNorm();
            if (d2 <= r2) f(i, d2);
          }
        }
      }
    }
  }

  // The nearest point within `radius` (<= cell) and its squared distance; index -1 if none.
  std::pair<std::int64_t, double> nearest(const engine::Vec3& q, double radius) const;
  double cell() const { return cell_; }

 private:
  struct Key {
    std::int64_t x = 0, y = 0, z = 0;
  };
  struct Range {
    std::uint32_t begin = 0, end = 0;
  };
  Key key_of(const engine::Vec3& p) const;
  static std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z);

  std::span<const engine::Vec3> points_;
  double cell_ = 1.0;
  engine::Vec3 origin_ = engine::Vec3::Zero();
  std::vector<std::uint32_t> order_;  // point indices sorted by cell
  std::unordered_map<std::uint64_t, Range> cells_;
};

// One representative per occupied voxel of side `voxel`, in voxel-key order: the centroid of
// the voxel's points (centroid = true), or the index of the point nearest to it. It picks the
// model's keypoints, which the features cache stores: a change to which point it picks must
// bump kModelFeaturesRevision (model_features.hpp).
struct Voxelised {
  std::vector<engine::Vec3> centroids;
  std::vector<std::uint32_t> nearest;  // the point nearest to each centroid
  std::vector<std::uint32_t> counts;   // points per voxel
};
Voxelised voxelise(std::span<const engine::Vec3> points, double voxel);
// The points per voxel of voxelise(points, voxel) (its counts alone, without the centroids).
std::vector<std::uint32_t> voxel_counts(std::span<const engine::Vec3> points, double voxel);
// The fewest points a voxel of the scanned surface holds, as far as counts can tell: half the
// voxel count of a typical point (half of the points lie in voxels holding at least that
// many: a median over points, not voxels, which clutter's many sparse voxels would decide), and
// at least `floor`. Clutter spread through a scan's box leaves one to three points in most
// voxels around the part; a surface voxel holds about as many as the typical point's (NIST
// CTC-02, 50,000 points, 30% outliers: a typical point's voxel holds 9, most clutter voxels 1-3;
// a quarter of it, 2, kept a third of the clutter's voxels and 468 keypoints, too few).
std::uint32_t surface_voxel_count(std::span<const std::uint32_t> counts, std::uint32_t floor);

}  // namespace nurbsreg::registration::detail
