#pragma once
// Analytic model shapes with exact closest points: planes (infinite or clipped to rectangles),
// spheres and open cylinders, and finders over one or several of them. They let ICP be tested
// against exact answers independently of the NURBS projection engine, and serve demos.
//
// All functions here are const and thread-safe; closest_point() never allocates.

#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "nurbsreg/icp/correspondence.hpp"

namespace nurbsreg::icp {

// Infinite plane through `origin` with unit `normal`.
struct Plane {
  engine::Vec3 origin = engine::Vec3::Zero();
  engine::Vec3 normal = engine::Vec3::UnitZ();
};

// Rectangle: origin + x * axis_u + y * axis_v with |x| <= half_u, |y| <= half_v. axis_u and
// axis_v are orthonormal; the normal is axis_u x axis_v.
struct Rectangle {
  engine::Vec3 origin = engine::Vec3::Zero();
  engine::Vec3 axis_u = engine::Vec3::UnitX();
  engine::Vec3 axis_v = engine::Vec3::UnitY();
  double half_u = 1.0;
  double half_v = 1.0;
};

struct Sphere {
  engine::Vec3 center = engine::Vec3::Zero();
  double radius = 1.0;
};

// Lateral surface of a cylinder (no caps): points at `radius` from the axis line
// origin + s * axis (unit), |s| <= half_length (infinity: unbounded).
struct Cylinder {
  engine::Vec3 origin = engine::Vec3::Zero();
  engine::Vec3 axis = engine::Vec3::UnitZ();
  double radius = 1.0;
  double half_length = std::numeric_limits<double>::infinity();
};

using Primitive = std::variant<Plane, Rectangle, Sphere, Cylinder>;

// An error naming the field (`sphere: radius: must be > 0 (got -1)`), or nothing.
std::optional<std::string> validate(const Primitive& primitive);

// Exact closest point of `p` on the primitive, with the unit surface normal there (for
// boundary feet of rectangles and finite cylinders: the normal of the surface at that edge
// point). Points on an axis or at a centre, where the foot is not unique, get a deterministic
// choice. `valid` is always true.
Correspondence closest_point(const Primitive& primitive, const engine::Vec3& p);

// Surface area (infinity for unbounded primitives).
double area(const Primitive& primitive);

// `count` points sampled uniformly by area over the (bounded) primitives, deterministically
// from `seed` (own generator on top of std::mt19937_64, identical on every platform).
// Throws std::invalid_argument naming the primitive if one is unbounded or invalid.
// Allocates the returned vector.
std::vector<engine::Vec3> sample_uniform(std::span<const Primitive> primitives, std::size_t count,
                                         std::uint64_t seed);

// Closest point over a union of primitives: the primitive with the smallest distance wins
// (the first one on ties). With 3 spheres and a plane the pose of a scan is fully constrained;
// a single plane, sphere or cylinder leaves free directions that the solver must report.
// Stateless; find() runs a tbb::parallel_for when query.parallel.
class UnionFinder : public CorrespondenceFinder {
 public:
  // Throws std::invalid_argument naming the primitive and field if one is invalid or the
  // list is empty.
  explicit UnionFinder(std::vector<Primitive> primitives);

  const std::vector<Primitive>& primitives() const { return primitives_; }
  void find(const CorrespondenceQuery& query, std::span<Correspondence> out) override;

 private:
  std::vector<Primitive> primitives_;
};

// A single infinite plane.
class PlaneFinder : public UnionFinder {
 public:
  explicit PlaneFinder(const Plane& plane) : UnionFinder({plane}) {}
};

// A single sphere.
class SphereFinder : public UnionFinder {
 public:
  explicit SphereFinder(const Sphere& sphere) : UnionFinder({sphere}) {}
};

}  // namespace nurbsreg::icp
