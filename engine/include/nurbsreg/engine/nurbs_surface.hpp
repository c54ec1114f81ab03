#pragma once
// A NURBS surface as plain, editable data. Evaluation is const, thread-safe and allocation-free.

#include <optional>
#include <string>
#include <vector>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine {

// Point and partial derivatives of a surface at (u, v).
struct SurfaceDerivatives {
  Vec3 s, su, sv, suu, suv, svv;
};

struct NurbsSurface {
  std::string name;
  int degree_u = 0;
  int degree_v = 0;
  std::vector<double> knots_u;
  std::vector<double> knots_v;
  int count_u = 0;
  int count_v = 0;
  // Row-major: control point (i, j) is at [i * count_v + j]; i runs along u, j along v.
  std::vector<Vec3> control_points;
  // Empty means non-rational; otherwise same layout as control_points, all > 0.
  std::vector<double> weights;

  bool is_rational() const { return !weights.empty(); }
  const Vec3& point(int i, int j) const { return control_points[i * count_v + j]; }
  double weight(int i, int j) const { return weights.empty() ? 1.0 : weights[i * count_v + j]; }
  Vec4 homogeneous(int i, int j) const;
  ParamInterval domain_u() const;
  ParamInterval domain_v() const;

  // An error naming the field, or nothing.
  std::optional<std::string> validate() const;

  // S(u, v); parameters outside the domain are clamped to it.
  Vec3 evaluate(double u, double v) const;
  // S and its first and second partial derivatives (The NURBS Book A3.6 + A4.4).
  SurfaceDerivatives derivatives(double u, double v) const;
};

}  // namespace nurbsreg::engine
