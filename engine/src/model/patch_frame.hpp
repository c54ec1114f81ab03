#pragma once
// Internal: the frame of a Bézier patch's control net, in which its oriented box is thin along
// the normal for a nearly flat patch (the hierarchy's lower bound, and the preparation's test of
// how far a patch is from flat).

#include "nurbsreg/engine/bezier.hpp"

namespace nurbsreg::engine {

// a = the direction between the net's first and last rows, n the normal of the plane of its two
// diagonals made orthogonal to a, b = n x a; the axes as (a, b, n). Any orthonormal frame gives a
// valid bound (the control points are projected on each axis). A degenerate net gets x, y, z.
void oriented_axes(const BezierPatch& bp, Vec3 axis[3]);

// The control points' extent along each axis: the patch lies in lo[k] <= axis[k] . x <= hi[k]
// (convex hull property), up to the rounding of the projections.
void extents_along(const BezierPatch& bp, const Vec3 axis[3], double lo[3], double hi[3]);

}  // namespace nurbsreg::engine
