#include "point_grid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numeric>

#include "grid_cell.hpp"

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

// Where cell coordinates are counted from: the points' lower corner, unless an axis spans 2^20
// cells or more (a stray point far from the rest: a scanner's glitch at 1e14 among a part's
// points). There (p - corner) / cell would round away the part's cells, or pass the clamp of
// cell_index, and put all of its points in a few cells; the coordinate-wise median keeps them
// exact (and only such clouds change: the radix sort's range ends at 2^20 too).
engine::Vec3 grid_origin(std::span<const engine::Vec3> points, double cell) {
  const engine::Vec3 lo = lower_corner(points);
  engine::Vec3 hi = lo;
  for (const engine::Vec3& p : points)
    hi = hi.cwiseMax(p);
  if (!(((hi - lo) / cell).maxCoeff() >= static_cast<double>(kBias))) return lo;
  std::vector<double> axis(points.size());
  const auto middle = axis.begin() + static_cast<std::ptrdiff_t>(points.size() / 2);
  engine::Vec3 median;
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < points.size(); ++i)
      axis[i] = points[i][a];
    std::nth_element(axis.begin(), middle, axis.end());
    median[a] = *middle;
  }
  return median;
}

// Integer cell coordinates of a point relative to the grid's origin (grid_origin: the points'
// lower corner, so never negative, unless a stray point makes the grid too large):
// floor((p - origin) / cell) per axis, as both packings below compute them.
std::array<std::int64_t, 3> cell_coordinates(const engine::Vec3& p, const engine::Vec3& origin,
                                             double cell) {
  const engine::Vec3 s = (p - origin) / cell;
  return {cell_index(s.x()), cell_index(s.y()), cell_index(s.z())};
}

// The point indices in the order of (packed cell key, index), keys[i] being point i's packed key,
// for packings that order cells by (x, y, z) lexicographically while every coordinate is in
// [0, 2^20). Instead of comparing pairs, a stable LSD radix sort of the indices by the cells'
// dense number (x * ny + y) * nz + z over the occupied box: the same order (stable, from index
// order), in a few passes over the points. Outside that range (a huge grid, or cells beyond the
// packings' monotone range) the comparison sort.
std::vector<std::uint32_t> cell_order(std::span<const std::array<std::int64_t, 3>> cells,
                                      std::span<const std::uint64_t> keys) {
  const std::size_t n = cells.size();
  std::vector<std::uint32_t> order(n);
  std::array<std::int64_t, 3> top{0, 0, 0};
  bool in_range = true;
  for (const auto& c : cells) {
    for (int a = 0; a < 3; ++a) {
      in_range = in_range && c[a] >= 0 && c[a] < kBias;
      top[a] = std::max(top[a], c[a]);
    }
  }
  const double box = static_cast<double>(top[0] + 1) * static_cast<double>(top[1] + 1) *
                     static_cast<double>(top[2] + 1);
  if (!in_range || box >= 4294967296.0) {
    std::iota(order.begin(), order.end(), std::uint32_t{0});
    std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
      return keys[a] != keys[b] ? keys[a] < keys[b] : a < b;
    });
    return order;
  }
  const auto ny = static_cast<std::uint64_t>(top[1] + 1);
  const auto nz = static_cast<std::uint64_t>(top[2] + 1);
  std::vector<std::uint32_t> dense(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto& c = cells[i];
    dense[i] = static_cast<std::uint32_t>(
        (static_cast<std::uint64_t>(c[0]) * ny + static_cast<std::uint64_t>(c[1])) * nz +
        static_cast<std::uint64_t>(c[2]));
  }
  constexpr int kDigit = 11;
  constexpr std::uint32_t kBuckets = 1u << kDigit;
  int bits = 0;
  while (bits < 32 && (static_cast<std::uint64_t>(box) - 1) >> bits != 0)
    ++bits;
  std::iota(order.begin(), order.end(), std::uint32_t{0});
  std::vector<std::uint32_t> next(n);
  std::vector<std::uint32_t> start(kBuckets);
  for (int shift = 0; shift < bits; shift += kDigit) {
    std::fill(start.begin(), start.end(), 0u);
    for (const std::uint32_t i : order)
      ++start[(dense[i] >> shift) & (kBuckets - 1)];
    std::uint32_t sum = 0;
    for (std::uint32_t& b : start) {
      const std::uint32_t count = b;
      b = sum;
      sum += count;
    }
    for (const std::uint32_t i : order)
      next[start[(dense[i] >> shift) & (kBuckets - 1)]++] = i;
    order.swap(next);
  }
  return order;
}

}  // namespace

std::uint64_t PointGrid::pack(std::int64_t x, std::int64_t y, std::int64_t z) {
  return (static_cast<std::uint64_t>((x + kBias) & kMask) << 42) |
         (static_cast<std::uint64_t>((y + kBias) & kMask) << 21) |
         static_cast<std::uint64_t>((z + kBias) & kMask);
}

PointGrid::Key PointGrid::key_of(const engine::Vec3& p) const {
  const engine::Vec3 s = (p - origin_) / cell_;
  return {cell_index(s.x()), cell_index(s.y()), cell_index(s.z())};
}

PointGrid::PointGrid(std::span<const engine::Vec3> points, double cell)
    : points_(points), cell_(cell), origin_(grid_origin(points, cell)) {
  std::vector<std::array<std::int64_t, 3>> cells(points.size());
  std::vector<std::uint64_t> keys(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Key k = key_of(points[i]);
    cells[i] = {k.x, k.y, k.z};
    keys[i] = pack(k.x, k.y, k.z);
  }
  order_ = cell_order(cells, keys);
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

namespace {

// Every point's voxel key with its index, sorted (by key, then index).
std::vector<std::pair<std::uint64_t, std::uint32_t>> voxel_keys(
    std::span<const engine::Vec3> points, double voxel) {
  const engine::Vec3 origin = grid_origin(points, voxel);
  std::vector<std::array<std::int64_t, 3>> cells(points.size());
  std::vector<std::uint64_t> keys(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    cells[i] = cell_coordinates(points[i], origin, voxel);
    const auto c = [](std::int64_t x) { return static_cast<std::uint64_t>(x) & kMask; };
    keys[i] = (c(cells[i][0]) << 42) | (c(cells[i][1]) << 21) | c(cells[i][2]);
  }
  const std::vector<std::uint32_t> order = cell_order(cells, keys);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(points.size());
  for (std::size_t k = 0; k < order.size(); ++k)
    keyed[k] = {keys[order[k]], order[k]};
  return keyed;
}

}  // namespace

std::vector<std::uint32_t> voxel_counts(std::span<const engine::Vec3> points, double voxel) {
  std::vector<std::uint32_t> counts;
  if (points.empty()) return counts;
  const std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed = voxel_keys(points, voxel);
  for (std::size_t k = 0; k < keyed.size();) {
    std::size_t e = k + 1;
    while (e < keyed.size() && keyed[e].first == keyed[k].first)
      ++e;
    counts.push_back(static_cast<std::uint32_t>(e - k));
    k = e;
  }
  return counts;
}

std::uint32_t surface_voxel_count(std::span<const std::uint32_t> counts, std::uint32_t floor) {
  std::vector<std::uint32_t> sorted(counts.begin(), counts.end());
  std::sort(sorted.begin(), sorted.end(), std::greater<>());
  std::uint64_t total = 0;
  for (const std::uint32_t c : sorted)
    total += c;
  std::uint64_t seen = 0;
  std::uint32_t typical = 1;
  for (const std::uint32_t c : sorted) {
    seen += c;
    if (2 * seen >= total) {
      typical = c;
      break;
    }
  }
  return std::max(floor, typical / 2);
}

Voxelised voxelise(std::span<const engine::Vec3> points, double voxel) {
  Voxelised out;
  if (points.empty()) return out;
  const std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed = voxel_keys(points, voxel);
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
