#pragma once
// Trim loops made of straight uv segments, for tests and benchmarks of trimmed faces: the engine
// computes their exact 3-D edges itself (no 3-D curves given).

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

}  // namespace nurbsreg::test
