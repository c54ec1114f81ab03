// ModelCorrespondenceFinder's boundary flag (IcpOptions::reject_boundary) on a trimmed face: a
// point beyond the edge of a square hole, whose closest face point is on the hole's rim, is
// marked on_boundary; a point over the face's interior and a point whose foot is an orthogonal
// projection are not. The rim is a trim loop, not the surface's domain boundary, so this needs
// the engine's on_trim_edge report.
#include <gtest/gtest.h>

#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/icp/model_finder.hpp"

namespace nurbsreg::icp {
namespace {

using engine::Vec3;

// The unit square z = 0 (bilinear, u = x, v = y) with the square hole [0.4, 0.6]^2 cut out by a
// degree-1 uv loop (the engine maps its edges to 3-D itself).
engine::Model square_with_hole() {
  engine::NurbsSurface s;
  s.name = "square with a hole";
  s.degree_u = s.degree_v = 1;
  s.count_u = s.count_v = 2;
  s.knots_u = s.knots_v = {0, 0, 1, 1};
  s.control_points = {Vec3(0, 0, 0), Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(1, 1, 0)};
  auto loop = [](std::vector<Vec3> corners) {
    engine::NurbsCurve c;
    c.degree = 1;
    c.dimension = 2;
    corners.push_back(corners.front());
    c.control_points = corners;
    c.knots = {0.0};
    for (std::size_t i = 0; i < corners.size(); ++i)
      c.knots.push_back(static_cast<double>(i));
    c.knots.push_back(static_cast<double>(corners.size() - 1));
    return engine::TrimLoop{{engine::TrimCurve{c, std::nullopt}}};
  };
  s.trim_loops.push_back(loop({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)}));
  s.trim_loops.push_back(
      loop({Vec3(0.4, 0.4, 0), Vec3(0.6, 0.4, 0), Vec3(0.6, 0.6, 0), Vec3(0.4, 0.6, 0)}));
  engine::Model m;
  m.surfaces.push_back(s);
  return m;
}

TEST(ModelFinderBoundary, FeetOnATrimLoopOffTheNormalAreOnTheBoundary) {
  const engine::PreparedModel model(square_with_hole());
  ModelCorrespondenceFinder finder(model);
  const std::vector<Vec3> points = {
      Vec3(0.45, 0.5, 0.0),   // in the hole's plane: foot on the rim, offset along the face
      Vec3(0.45, 0.5, 0.01),  // just above the hole: foot on the rim, offset mostly sideways
      Vec3(0.2, 0.2, 0.3),    // over the face: orthogonal foot inside
      Vec3(0.2, 0.5, -0.1),   // under the face: orthogonal foot inside
  };
  finder.reset(points.size());
  CorrespondenceQuery query;
  query.points = points;
  std::vector<Correspondence> out(points.size());
  finder.find(query, out);
  for (const Correspondence& c : out)
    ASSERT_TRUE(c.valid);
  EXPECT_NEAR(out[0].foot.x(), 0.4, 1e-12);
  EXPECT_TRUE(out[0].on_boundary);
  EXPECT_TRUE(out[1].on_boundary);
  EXPECT_FALSE(out[2].on_boundary);
  EXPECT_FALSE(out[3].on_boundary);
}

}  // namespace
}  // namespace nurbsreg::icp
