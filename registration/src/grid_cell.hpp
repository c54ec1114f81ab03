#pragma once
// Internal to registration: a point's integer cell coordinate on a uniform grid, shared by the
// grids that hash cells (point_grid.cpp, verdict.cpp, hypotheses.cpp).

#include <cmath>
#include <cstdint>

namespace nurbsreg::registration::detail {

// floor(x) as an integer for x = a coordinate over the cell size, clamped to +-2^53. A tiny cell
// (a stored voxel from a corrupt cache entry) or a point far from the rest (a finite scan point
// at 1e30) makes x exceed what a 64-bit integer holds, and converting it is undefined. The clamp
// is monotone and never moves two coordinates further apart, so cells that differ by at most one
// still do: the neighbour searches, which look one cell each way and then compare distances,
// find the same points. NaN (a zero cell) gives the lower limit.
inline std::int64_t cell_index(double x) {
  constexpr double kLimit = 9007199254740992.0;  // 2^53: every integer up to it is a double
  const double f = std::floor(x);
  if (!(f > -kLimit)) return -static_cast<std::int64_t>(kLimit);
  if (f > kLimit) return static_cast<std::int64_t>(kLimit);
  return static_cast<std::int64_t>(f);
}

}  // namespace nurbsreg::registration::detail
