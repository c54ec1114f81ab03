#include "trim/rectangle_face.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace nurbsreg::engine {

std::optional<UvRectangle> rectangle_of_face(const NurbsSurface& surface) {
  if (surface.trim_loops.size() != 1) return std::nullopt;
  const TrimLoop& loop = surface.trim_loops.front();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  double u0 = kInf, u1 = -kInf, v0 = kInf, v1 = -kInf;
  for (const TrimCurve& curve : loop.curves) {
    for (const Vec3& c : curve.uv.control_points) {
      u0 = std::min(u0, c.x());
      u1 = std::max(u1, c.x());
      v0 = std::min(v0, c.y());
      v1 = std::max(v1, c.y());
    }
  }
  if (!(u1 > u0) || !(v1 > v0) || !std::isfinite(u1 - u0) || !std::isfinite(v1 - v0)) {
    return std::nullopt;
  }
  const double tol_u = 1e-12 * (u1 - u0), tol_v = 1e-12 * (v1 - v0);
  // Every control point of the curve within tol of x = at along `axis` (0: u, 1: v).
  const auto on_line = [](const TrimCurve& curve, int axis, double at, double tol) {
    return std::all_of(curve.uv.control_points.begin(), curve.uv.control_points.end(),
                       [&](const Vec3& c) { return std::abs(c[axis] - at) <= tol; });
  };
  // Within tol (twice, for a gap's points) of one of the rectangle's sides?
  const auto on_a_side = [&](const Vec3& a, const Vec3& b, double scale) {
    const auto near = [](double x, double at, double tol) { return std::abs(x - at) <= tol; };
    return (near(a.x(), u0, scale * tol_u) && near(b.x(), u0, scale * tol_u)) ||
           (near(a.x(), u1, scale * tol_u) && near(b.x(), u1, scale * tol_u)) ||
           (near(a.y(), v0, scale * tol_v) && near(b.y(), v0, scale * tol_v)) ||
           (near(a.y(), v1, scale * tol_v) && near(b.y(), v1, scale * tol_v));
  };
  double area = 0.0;  // of u dv around the loop
  const std::size_t count = loop.curves.size();
  for (std::size_t k = 0; k < count; ++k) {
    const TrimCurve& curve = loop.curves[k];
    if (!(on_line(curve, 0, u0, tol_u) || on_line(curve, 0, u1, tol_u) ||
          on_line(curve, 1, v0, tol_v) || on_line(curve, 1, v1, tol_v))) {
      return std::nullopt;
    }
    // Its end points (a curve need not be clamped), and the straight segment that closes the
    // gap to the next curve's start (TrimLoop), which must run along a side too.
    const Vec3 first = curve.uv.evaluate(curve.uv.domain().lo);
    const Vec3 last = curve.uv.evaluate(curve.uv.domain().hi);
    const TrimCurve& following = loop.curves[(k + 1) % count];
    const Vec3 next = following.uv.evaluate(following.uv.domain().lo);
    if (!on_a_side(last, next, 2.0)) return std::nullopt;
    // u dv along the curve: on a vertical side u is constant (first.x() within tol), on a
    // horizontal one dv is 0, exactly as from the end points; along the gap, the trapezoid.
    area += 0.5 * (first.x() + last.x()) * (last.y() - first.y());
    area += 0.5 * (last.x() + next.x()) * (next.y() - last.y());
  }
  const double rectangle = (u1 - u0) * (v1 - v0);
  if (!(std::abs(std::abs(area) - rectangle) <= 1e-10 * rectangle)) return std::nullopt;
  // The face is the rectangle within the domain (a loop beyond the domain trims nothing there).
  const ParamInterval du = surface.domain_u(), dv = surface.domain_v();
  UvRectangle r{{std::max(u0, du.lo), std::min(u1, du.hi)},
                {std::max(v0, dv.lo), std::min(v1, dv.hi)}};
  if (!(r.u.hi > r.u.lo) || !(r.v.hi > r.v.lo)) return std::nullopt;
  return r;
}

}  // namespace nurbsreg::engine
