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

// Spreads the low 10 bits of x to every third bit (bit k goes to bit 3k).
constexpr std::uint32_t spread_bits(std::uint32_t x) {
  std::uint32_t out = 0;
  for (int k = 0; k < kMaxOrderBits; ++k)
    out |= ((x >> k) & 1u) << (3 * k);
  return out;
}

struct SpreadTable {
  std::uint32_t value[1u << kMaxOrderBits];
  constexpr SpreadTable() : value() {
    for (std::uint32_t x = 0; x < (1u << kMaxOrderBits); ++x)
      value[x] = spread_bits(x);
  }
};
constexpr SpreadTable kSpread;

// Bits per axis: about four points per cell, between 2^2 and 2^7 cells along an axis.
int bits_per_axis(std::size_t points) {
  const double per_axis = std::log2(std::max<double>(1.0, static_cast<double>(points) / 4.0)) / 3.0;
  return std::clamp(static_cast<int>(per_axis), 2, 7);
}

// Fills `order` with 0 .. n - 1 sorted by scratch.key (key_bits wide): a least-significant-digit
// radix sort, two stable counting passes over half the bits each, so points of one cell keep
// their input order as the single counting sort does.
void radix_sort(SpatialOrderScratch& scratch, FrameVector<std::uint32_t>& order, int key_bits) {
  const std::size_t n = scratch.key.size();
  const int low_bits = (key_bits + 1) / 2;
  scratch.start.assign(std::size_t{1} << low_bits, 0);
  scratch.pass.resize(n);
  // Pass 1 by the low bits into `pass`, pass 2 by the high bits into `order`.
  const std::uint32_t low_mask = (1u << low_bits) - 1u;
  const auto counting_pass = [&](auto digit, auto source, FrameVector<std::uint32_t>& into) {
    std::fill(scratch.start.begin(), scratch.start.end(), 0u);
    for (std::size_t k = 0; k < n; ++k)
      ++scratch.start[digit(scratch.key[source(k)])];
    std::uint32_t sum = 0;
    for (std::uint32_t& c : scratch.start) {
      const std::uint32_t count = c;
      c = sum;
      sum += count;
    }
    for (std::size_t k = 0; k < n; ++k) {
      const std::uint32_t i = source(k);
      into[scratch.start[digit(scratch.key[i])]++] = i;
    }
  };
  counting_pass([low_mask](std::uint32_t key) { return key & low_mask; },
                [](std::size_t k) { return static_cast<std::uint32_t>(k); }, scratch.pass);
  counting_pass([low_bits](std::uint32_t key) { return key >> low_bits; },
                [&scratch](std::size_t k) { return scratch.pass[k]; }, order);
}

}  // namespace

void spatial_order(PointView points, FrameVector<std::uint32_t>& order,
                   SpatialOrderScratch& scratch, int fine_bits) {
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
  const int bits = fine_bits > 0 ? std::min(fine_bits, kMaxOrderBits) : bits_per_axis(n);
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
  if (bits > kCountingSortBits) {
    radix_sort(scratch, order, 3 * bits);
    return;
  }
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
