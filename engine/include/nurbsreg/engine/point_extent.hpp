#pragma once
// The extent of a cloud of points that a few stray points far from the rest do not decide: a
// scanner's glitch at 1e14 among a part's points, or a far wall's points in a scan of a part.
// What is derived from a scan's size (the scan-size warning, the fit verdict's tolerance floor,
// ICP's length scale) uses it.

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/projection.hpp"

namespace nurbsreg::engine {

// The box of the finite points less their extreme 0.1% on each side of each axis, taken on a
// sample of at most 65,536 points (every k-th, so the same points for any thread count), from
// 1,000 sampled points on; below that, the box of all finite points. Empty when none is finite.
Aabb trimmed_box(PointView points);

}  // namespace nurbsreg::engine
