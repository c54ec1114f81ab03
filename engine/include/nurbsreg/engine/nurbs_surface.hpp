#pragma once
// A NURBS surface as plain, editable data. Evaluation is const, thread-safe and allocation-free.

#include <optional>
#include <string>
#include <vector>

#include "nurbsreg/engine/nurbs_curve.hpp"
#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine {

// Point and partial derivatives of a surface at (u, v).
struct SurfaceDerivatives {
  Vec3 s, su, sv, suu, suv, svv;
};

// One edge use of a trimming loop (a trimmed CAD face's boundary).
//  - uv: the curve in the surface's (u, v) parameter space (dimension 2: x = u, y = v), oriented
//    along the loop.
//  - edge: the 3-D curve it traces on the surface, same direction (the CAD file's edge). Optional:
//    without it the engine computes the exact 3-D image of a degree-1 uv curve itself; a uv curve
//    of higher degree needs its edge (validate() says so).
struct TrimCurve {
  NurbsCurve uv;
  std::optional<NurbsCurve> edge;
};

// A closed loop of trim curves, end to start (small gaps, as CAD files have, are closed by the
// engine with straight segments in (u, v)).
struct TrimLoop {
  std::vector<TrimCurve> curves;
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

  // A trimmed face: the part of the domain inside the loops by the even-odd rule (a point is in
  // the face when a ray from it crosses the loops an odd number of times), so loop orientation
  // does not matter. Empty: the whole domain (an untrimmed surface).
  std::vector<TrimLoop> trim_loops;
  // The face's outer side is -(S_u x S_v) (a CAD face with orientation REVERSED): reported
  // normals and signed distances use the face's side, not the parametric one.
  bool reversed = false;

  bool is_rational() const { return !weights.empty(); }
  bool is_trimmed() const { return !trim_loops.empty(); }
  const Vec3& point(int i, int j) const { return control_points[i * count_v + j]; }
  double weight(int i, int j) const { return weights.empty() ? 1.0 : weights[i * count_v + j]; }
  Vec4 homogeneous(int i, int j) const;
  ParamInterval domain_u() const;
  ParamInterval domain_v() const;

  // An error naming the field, or nothing.
  std::optional<std::string> validate() const;
  // The trim loops' part of validate(): curve dimensions, edges where needed.
  std::optional<std::string> validate_trim_loops() const;

  // S(u, v); parameters outside the domain are clamped to it.
  Vec3 evaluate(double u, double v) const;
  // S and its first and second partial derivatives (The NURBS Book A3.6 + A4.4).
  SurfaceDerivatives derivatives(double u, double v) const;
};

}  // namespace nurbsreg::engine
