#include "point_grid.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace nurbsreg::registration::detail {
namespace {

// 21 bits per coordinate: a grid of two million cells a side around the origin.
constexpr std::int64_t kBias = std::int64_t{1} << 20;
constexpr std::int64_t kMask = (std::int64_t{1} << 21) - 1;

engine::Vec3 lower_corner(std::span<const engine::Vec3> points) {
  engine::Vec3 lo = engine::Vec3::Constant(std::numeric_limits<double>::infinity());
  for (const engine::Vec3& p : points)
    lo = lo.cwiseMin(p);
  return points.empty() ? engine::Vec3::Zero() : lo;
}

}  // namespace

std::uint64_t PointGrid::pack(std::int64_t x, std::int64_t y, std::int64_t z) {
  return (static_cast<std::uint64_t>((x + kBias) & kMask) << 42) |
         (static_cast<std::uint64_t>((y + kBias) & kMask) << 21) |
         static_cast<std::uint64_t>((z + kBias) & kMask);
}

PointGrid::Key PointGrid::key_of(const engine::Vec3& p) const {
  const engine::Vec3 s = (p - origin_) / cell_;
  return {static_cast<std::int64_t>(std::floor(s.x())),
          static_cast<std::int64_t>(std::floor(s.y())),
          static_cast<std::int64_t>(std::floor(s.z()))};
}

PointGrid::PointGrid(std::span<const engine::Vec3> points, double cell)
    : points_(points), cell_(cell), origin_(lower_corner(points)) {
  std::vector<std::uint64_t> keys(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Key k = key_of(points[i]);
    keys[i] = pack(k.x, k.y, k.z);
  }
  order_.resize(points.size());
  std::iota(order_.begin(), order_.end(), std::uint32_t{0});
  std::sort(order_.begin(), order_.end(), [&](std::uint32_t a, std::uint32_t b) {
    return keys[a] != keys[b] ? keys[a] < keys[b] : a < b;
  });
  cells_.reserve(points.size() / 4 + 1);
  for (std::uint32_t k = 0; k < order_.size();) {
    std::uint32_t e = k + 1;
    while (e < order_.size() && keys[order_[e]] == keys[order_[k]])
      ++e;
    cells_.emplace(keys[order_[k]], Range{k, e});
    k = e;
  }
}

std::pair<std::int64_t, double> PointGrid::nearest(const engine::Vec3& q, double radius) const {
  std::int64_t best = -1;
  double best_d2 = std::numeric_limits<double>::infinity();
  for_each_within(q, radius, [&](std::uint32_t i, double d2) {
    if (d2 < best_d2 || (d2 == best_d2 && i < best)) {
      best_d2 = d2;
      best = i;
    }
  });
  return {best, best_d2};
}

Voxelised voxelise(std::span<const engine::Vec3> points, double voxel) {
  Voxelised out;
  if (points.empty()) return out;
  const engine::Vec3 origin = lower_corner(points);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const engine::Vec3 s = (points[i] - origin) / voxel;
    const auto c = [](double x) { return static_cast<std::uint64_t>(std::floor(x)) & kMask; };
    keyed[i] = {(c(s.x()) << 42) | (c(s.y()) << 21) | c(s.z()), static_cast<std::uint32_t>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  for (std::size_t k = 0; k < keyed.size();) {
    std::size_t e = k + 1;
    while (e < keyed.size() && keyed[e].first == keyed[k].first)
      ++e;
    engine::Vec3 sum = engine::Vec3::Zero();
    for (std::size_t j = k; j < e; ++j)
      sum += points[keyed[j].second];
    const engine::Vec3 c = sum / static_cast<double>(e - k);
    std::uint32_t best = keyed[k].second;
    double best_d2 = std::numeric_limits<double>::infinity();
    for (std::size_t j = k; j < e; ++j) {
      const double d2 = (points[keyed[j].second] - c).squaredNorm();
      if (d2 < best_d2) {
        best_d2 = d2;
        best = keyed[j].second;
      }
    }
    out.centroids.push_back(c);
    out.nearest.push_back(best);
    out.counts.push_back(static_cast<std::uint32_t>(e - k));
    k = e;
  }
  return out;
}

}  // namespace nurbsreg::registration::detail
