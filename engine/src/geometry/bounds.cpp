#include "nurbsreg/engine/bounds.hpp"

#include <algorithm>
#include <cmath>

namespace nurbsreg::engine {
namespace {

template <typename PointAt>
BoundingSphere sphere_around(const Aabb& box, int count, PointAt point_at) {
  BoundingSphere s;
  s.center = box.center();
  double r2 = 0.0;
  for (int i = 0; i < count; ++i)
    r2 = std::max(r2, (point_at(i) - s.center).squaredNorm());
  s.radius = std::sqrt(r2);
  return s;
}

}  // namespace

Aabb bounding_box(const BezierCurve& piece) {
  Aabb box;
  for (int i = 0; i <= piece.degree; ++i)
    box.extend(piece.point(i));
  return box;
}

Aabb bounding_box(const BezierPatch& patch) {
  Aabb box;
  for (const Vec4& c : patch.cw)
    box.extend(Vec3(c.head<3>() / c[3]));
  return box;
}

BoundingSphere bounding_sphere(const BezierCurve& piece) {
  return sphere_around(bounding_box(piece), piece.degree + 1,
                       [&](int i) { return piece.point(i); });
}

BoundingSphere bounding_sphere(const BezierPatch& patch) {
  return sphere_around(bounding_box(patch), static_cast<int>(patch.cw.size()),
                       [&](int i) { return Vec3(patch.cw[i].head<3>() / patch.cw[i][3]); });
}

}  // namespace nurbsreg::engine
