#pragma once
// Bounding volumes from control points: by the convex hull property (positive weights) they
// contain the piece or patch.

#include <algorithm>
#include <limits>
#include <span>

#include "nurbsreg/engine/bezier.hpp"

namespace nurbsreg::engine {

struct Aabb {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = Vec3::Constant(-std::numeric_limits<double>::infinity());

  void extend(const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void extend(const Aabb& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
  bool empty() const { return lo.x() > hi.x(); }
  Vec3 center() const { return 0.5 * (lo + hi); }
  double diagonal() const { return empty() ? 0.0 : (hi - lo).norm(); }
  // Squared distance from p to the box (0 inside).
  double squared_distance(const Vec3& p) const {
    return (lo - p).cwiseMax(0.0).cwiseMax(p - hi).squaredNorm();
  }
};

struct BoundingSphere {
  Vec3 center = Vec3::Zero();
  double radius = 0.0;

  // Squared distance from p to the ball (0 inside).
  double squared_distance(const Vec3& p) const {
    const double d = std::max(0.0, (p - center).norm() - radius);
    return d * d;
  }
};

Aabb bounding_box(const BezierCurve& piece);
Aabb bounding_box(const BezierPatch& patch);
// Centred on the box centre, radius to the farthest control point (not minimal, but cheap and
// tight enough for pruning).
BoundingSphere bounding_sphere(const BezierCurve& piece);
BoundingSphere bounding_sphere(const BezierPatch& patch);

}  // namespace nurbsreg::engine
