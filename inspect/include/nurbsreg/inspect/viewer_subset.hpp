#pragma once
// A spatially even subset of a large scan for the report's 3-D viewer (a browser draws a few
// hundred thousand points smoothly, not millions): one point per occupied cell of a cubic grid,
// the first in scan order, with the cell size chosen so that at most `max_points` cells are
// occupied. Dense parts of a scan are thinned more than sparse ones, so the picture keeps its
// coverage. Statistics never use this subset. Deterministic; allocates O(points) scratch.

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::inspect {

struct ViewerSubset {
  std::vector<std::uint32_t> indices;  // into the input points, increasing
  double cell = 0.0;                   // grid cell side (0: every point kept)
};

ViewerSubset viewer_subset(std::span<const engine::Vec3> points, std::size_t max_points);

}  // namespace nurbsreg::inspect
