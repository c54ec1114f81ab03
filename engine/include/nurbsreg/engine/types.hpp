#pragma once
// Basic value types shared by every engine header.

#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products, rotations: used throughout

namespace nurbsreg::engine {

// How a batch call runs: on the calling thread only (debugging, and the reference of the
// "parallel == serial" tests), or in parallel with TBB in the caller's task arena. Results are
// the same either way. Projector spells it project() / project_serial().
enum class Execution : std::uint8_t { serial, parallel };

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
// Homogeneous control point (w*x, w*y, w*z, w): rational evaluation, knot insertion and
// subdivision all act linearly on these (The NURBS Book, ch. 4).
using Vec4 = Eigen::Vector4d;

// Highest degree accepted in either direction. Validation rejects anything above it so that
// every hot path can use fixed-size arrays (no heap allocation per call). Real CAD data in
// shared/data reaches degree 10 (linkrods.step); the squared-distance functions of the
// projectors have degree 2 * kMaxDegree.
inline constexpr int kMaxDegree = 12;

// Closed parameter interval [lo, hi] in the parameter space of a parent entity.
struct ParamInterval {
  double lo = 0.0;
  double hi = 1.0;
  double width() const { return hi - lo; }
  // Local t in [0, 1] -> parent parameter.
  double to_parent(double t) const { return lo + t * (hi - lo); }
  double to_local(double u) const { return (u - lo) / (hi - lo); }
};

}  // namespace nurbsreg::engine
