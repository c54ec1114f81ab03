#pragma once
// Exact rational NURBS representations of analytic shapes (The NURBS Book §7.3 and §8.5):
// used by the examples, the tests (known answers) and `synth`.

#include "nurbsreg/engine/nurbs_curve.hpp"
#include "nurbsreg/engine/nurbs_surface.hpp"

namespace nurbsreg::engine {

// Full circle in the plane z = center.z, degree 2, 9 control points, 4 quarter arcs; closed
// (first == last point), parameter in [0, 1].
NurbsCurve make_circle(const Vec3& center, double radius);

// Sphere as a surface of revolution about z: u in [0, 1] runs from the north pole (u = 0) to
// the south pole (u = 1), v in [0, 1] around the axis (seam at v = 0 == v = 1, at +x). Both
// u-boundaries are collapsed to a pole: degree (2, 2), 5 x 9 control points.
NurbsSurface make_sphere(const Vec3& center, double radius);

// Torus about the z axis through `center`: major radius R (tube centre), minor radius r < R.
// u around the tube, v around the axis; both directions closed. Degree (2, 2), 9 x 9 points.
NurbsSurface make_torus(const Vec3& center, double major_radius, double minor_radius);

}  // namespace nurbsreg::engine
