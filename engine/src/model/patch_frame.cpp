#include "model/patch_frame.hpp"

#include <algorithm>
#include <limits>

namespace nurbsreg::engine {

void oriented_axes(const BezierPatch& bp, Vec3 axis[3]) {
  const int p = bp.degree_u, q = bp.degree_v;
  auto point = [&](int i, int j) -> Vec3 {
    const Vec4& c = bp.at(i, j);
    return c.head<3>() / c[3];
  };
  Vec3 a = point(p, 0) + point(p, q) - point(0, 0) - point(0, q);
  Vec3 b = point(0, q) + point(p, q) - point(0, 0) - point(p, 0);
  Vec3 n = a.cross(b);
  if (!(a.norm() > 0.0) || !(n.norm() > 1e-12 * a.norm() * b.norm())) {
    axis[0] = Vec3::UnitX();
    axis[1] = Vec3::UnitY();
    axis[2] = Vec3::UnitZ();
    return;
  }
  a.normalize();
  n.normalize();
  axis[0] = a;
  axis[1] = n.cross(a).normalized();
  axis[2] = n;
}

void extents_along(const BezierPatch& bp, const Vec3 axis[3], double lo[3], double hi[3]) {
  for (int k = 0; k < 3; ++k) {
    lo[k] = std::numeric_limits<double>::infinity();
    hi[k] = -lo[k];
  }
  for (const Vec4& c : bp.cw) {
    const Vec3 x = c.head<3>() / c[3];
    for (int k = 0; k < 3; ++k) {
      const double y = axis[k].dot(x);
      lo[k] = std::min(lo[k], y);
      hi[k] = std::max(hi[k], y);
    }
  }
}

}  // namespace nurbsreg::engine
