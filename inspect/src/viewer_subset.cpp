#include "nurbsreg/inspect/viewer_subset.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <numeric>

namespace nurbsreg::inspect {
namespace {

constexpr std::uint64_t kEmpty = ~std::uint64_t{0};

// An open-addressing set of cell keys, reused over the passes of the cell-size search.
class CellSet {
 public:
  explicit CellSet(std::size_t points)
      : slots_(std::bit_ceil(std::max<std::size_t>(2 * points, 16)), kEmpty),
        mask_(slots_.size() - 1) {}
  void clear() {
    std::fill(slots_.begin(), slots_.end(), kEmpty);
    size_ = 0;
  }
  // True when `key` was not in the set yet.
  bool insert(std::uint64_t key) {
    std::size_t at = (key * 0x9E3779B97F4A7C15ull) >> 20 & mask_;
    while (slots_[at] != kEmpty) {
      if (slots_[at] == key) return false;
      at = (at + 1) & mask_;
    }
    slots_[at] = key;
    ++size_;
    return true;
  }
  std::size_t size() const { return size_; }

 private:
  std::vector<std::uint64_t> slots_;
  std::size_t mask_;
  std::size_t size_ = 0;
};

struct Grid {
  engine::Vec3 origin;
  double inverse_cell;
  std::uint64_t key(const engine::Vec3& p) const {
    // 21 bits per axis: the cell size search never asks for more than 2^21 cells per side.
    const auto c = ((p - origin) * inverse_cell).array().floor().cast<std::int64_t>();
    const auto clamp = [](std::int64_t x) {
      return static_cast<std::uint64_t>(std::clamp<std::int64_t>(x, 0, (1 << 21) - 1));
    };
    return clamp(c.x()) | clamp(c.y()) << 21 | clamp(c.z()) << 42;
  }
};

std::size_t occupied(std::span<const engine::Vec3> points, const Grid& grid, CellSet& set) {
  set.clear();
  for (const engine::Vec3& p : points)
    set.insert(grid.key(p));
  return set.size();
}

}  // namespace

ViewerSubset viewer_subset(std::span<const engine::Vec3> points, std::size_t max_points) {
  ViewerSubset out;
  if (points.size() <= max_points) {
    out.indices.resize(points.size());
    std::iota(out.indices.begin(), out.indices.end(), 0u);
    return out;
  }
  engine::Vec3 lo = points[0], hi = points[0];
  for (const engine::Vec3& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double extent = std::max((hi - lo).maxCoeff(), 1e-300);
  CellSet set(points.size());
  // A scan samples surfaces: occupied cells grow like 1 / cell^2. Start from the cell that would
  // give max_points cells on one face of the bounding cube and correct by that law.
  const double target = 0.95 * static_cast<double>(max_points);
  double cell = std::max(extent / std::sqrt(target), extent / double(1 << 20));
  std::size_t count = 0;
  for (int pass = 0; pass < 8; ++pass) {
    count = occupied(points, Grid{lo, 1.0 / cell}, set);
    if (count <= max_points && count >= 0.85 * max_points) break;
    cell *= std::sqrt(static_cast<double>(count) / target);
    cell = std::max(cell, extent / double(1 << 20));
  }
  while (count > max_points) {
    cell *= 1.05;
    count = occupied(points, Grid{lo, 1.0 / cell}, set);
  }
  const Grid grid{lo, 1.0 / cell};
  set.clear();
  out.indices.reserve(count);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (set.insert(grid.key(points[i]))) out.indices.push_back(static_cast<std::uint32_t>(i));
  }
  out.cell = cell;
  return out;
}

}  // namespace nurbsreg::inspect
