#include "nurbsreg/engine/point_extent.hpp"

#include <algorithm>
#include <vector>

namespace nurbsreg::engine {

Aabb trimmed_box(PointView points) {
  constexpr std::size_t kPlainBelow = 1000;
  constexpr std::size_t kMostSampled = 65536;
  constexpr double kTrimmed = 0.001;  // of the sample, on each side of each axis
  const std::size_t step = std::max<std::size_t>(1, points.size() / kMostSampled);
  std::vector<Vec3> sample;
  sample.reserve(std::min(points.size(), kMostSampled + 1));
  for (std::size_t i = 0; i < points.size(); i += step) {
    const Vec3 p = points[i];
    if (p.allFinite()) sample.push_back(p);
  }
  Aabb box;
  if (sample.size() < kPlainBelow) {
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Vec3 p = points[i];
      if (p.allFinite()) box.extend(p);
    }
    return box;
  }
  const std::size_t m = sample.size();
  const std::size_t cut = static_cast<std::size_t>(kTrimmed * static_cast<double>(m));
  std::vector<double> axis(m);
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < m; ++i)
      axis[i] = sample[i][a];
    const auto low = axis.begin() + static_cast<std::ptrdiff_t>(cut);
    std::nth_element(axis.begin(), low, axis.end());
    box.lo[a] = *low;
    const auto high = axis.begin() + static_cast<std::ptrdiff_t>(m - 1 - cut);
    std::nth_element(axis.begin(), high, axis.end());
    box.hi[a] = *high;
  }
  return box;
}

}  // namespace nurbsreg::engine
