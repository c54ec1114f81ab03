#include "nurbsreg/engine/spatial_order.hpp"
#include "nurbsreg/engine/cancellation.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <utility>

namespace nurbsreg::engine {
namespace {

// Spreads the low 7 bits of x to every third bit (bit k goes to bit 3k).
constexpr std::uint32_t spread_bits(std::uint32_t x) {
  std::uint32_t out = 0;
  for (int k = 0; k < 7; ++k)
    out |= ((x >> k) & 1u) << (3 * k);
  return out;
}

struct SpreadTable {
  std::uint32_t value[128];
  constexpr SpreadTable() : value() {
    for (std::uint32_t x = 0; x < 128; ++x)
      value[x] = spread_bits(x);
  }
};
constexpr SpreadTable kSpread;

// Bits per axis: about four points per cell, between 2^2 and 2^7 cells along an axis.
int bits_per_axis(std::size_t points) {
  const double per_axis = std::log2(std::max<double>(1.0, static_cast<double>(points) / 4.0)) / 3.0;
  return std::clamp(static_cast<int>(per_axis), 2, 7);
}

}  // namespace

void spatial_order(PointView points, FrameVector<std::uint32_t>& order,
                   SpatialOrderScratch& scratch) {
  const std::size_t n = points.size();
  order.resize(n);
  scratch.key.resize(n);
  // The finite points' bounding box, and then the keys, in parallel (the counting sort below is
  // serial: about half of the ordering's cost, ~1% of a cold frame's).
  constexpr std::size_t kGrain = 16384;
  using Box = std::pair<Vec3, Vec3>;
  const Box empty{Vec3::Constant(std::numeric_limits<double>::infinity()),
                  Vec3::Constant(-std::numeric_limits<double>::infinity())};
  const Box box = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, n, kGrain), empty,
      [&](const tbb::blocked_range<std::size_t>& r, Box b) {
        for (std::size_t i = r.begin(); i < r.end(); ++i) {
          const Vec3 p = points[i];
          if (!p.allFinite()) continue;
          b.first = b.first.cwiseMin(p);
          b.second = b.second.cwiseMax(p);
        }
        return b;
      },
      [](const Box& a, const Box& b) {
        return Box{a.first.cwiseMin(b.first), a.second.cwiseMax(b.second)};
      });
  nurbsreg::engine::stop_if_cancelled();
  const Vec3& lo = box.first;
  const Vec3& hi = box.second;
  const int bits = bits_per_axis(n);
  const std::uint32_t cells_per_axis = 1u << bits;
  // Cell size: the box's largest extent over the cells along an axis (cubic cells, so a flat
  // scan is not cut into slivers); a box of zero size puts every point in cell 0.
  const double extent = (hi - lo).maxCoeff();
  const double scale = extent > 0.0 ? cells_per_axis / extent : 0.0;
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, n, kGrain), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t i = r.begin(); i < r.end(); ++i) {
          const Vec3 p = points[i];
          std::uint32_t key = 0;
          if (p.allFinite()) {
            for (int a = 0; a < 3; ++a) {
              const double x = (p[a] - lo[a]) * scale;
              const auto c = static_cast<std::uint32_t>(std::min(x, double(cells_per_axis - 1)));
              key |= kSpread.value[c] << a;
            }
          }
          scratch.key[i] = key;
        }
      });
  nurbsreg::engine::stop_if_cancelled();
  // Stable counting sort by key.
  const std::size_t cells = std::size_t{1} << (3 * bits);
  scratch.start.assign(cells + 1, 0);
  for (std::size_t i = 0; i < n; ++i)
    ++scratch.start[scratch.key[i] + 1];
  for (std::size_t c = 1; c <= cells; ++c)
    scratch.start[c] += scratch.start[c - 1];
  for (std::size_t i = 0; i < n; ++i)
    order[scratch.start[scratch.key[i]]++] = static_cast<std::uint32_t>(i);
}

}  // namespace nurbsreg::engine
