#pragma once
// Trim loops made of straight uv segments, for tests and benchmarks of trimmed faces: the engine
// computes their exact 3-D edges itself (no 3-D curves given).

#include <algorithm>
#include <vector>

#include "nurbsreg/engine/nurbs_surface.hpp"

namespace nurbsreg::test {

// The degree-1 uv curve from a to b.
inline engine::NurbsCurve uv_line(const engine::Vec2& a, const engine::Vec2& b) {
  engine::NurbsCurve c;
  c.degree = 1;
  c.dimension = 2;
  c.knots = {0.0, 0.0, 1.0, 1.0};
  c.control_points = {engine::Vec3(a.x(), a.y(), 0.0), engine::Vec3(b.x(), b.y(), 0.0)};
  return c;
}

// The closed polygon through `corners` (the last one joins the first).
inline engine::TrimLoop polygon_loop(const std::vector<engine::Vec2>& corners) {
  engine::TrimLoop loop;
  for (std::size_t k = 0; k < corners.size(); ++k)
    loop.curves.push_back({uv_line(corners[k], corners[(k + 1) % corners.size()]), std::nullopt});
  return loop;
}

// The rectangle [u0, u1] x [v0, v1] as a polygon loop, counter-clockwise (clockwise when
// `reverse`), each side split into `pieces` segments.
inline engine::TrimLoop rectangle_loop(double u0, double u1, double v0, double v1, int pieces = 1,
                                       bool reverse = false) {
  const engine::Vec2 c[4] = {{u0, v0}, {u1, v0}, {u1, v1}, {u0, v1}};
  std::vector<engine::Vec2> corners;
  for (int k = 0; k < 4; ++k) {
    for (int i = 0; i < pieces; ++i)
      corners.push_back(c[k] + (c[(k + 1) % 4] - c[k]) * (double(i) / pieces));
  }
  if (reverse) std::reverse(corners.begin(), corners.end());
  return polygon_loop(corners);
}

}  // namespace nurbsreg::test
