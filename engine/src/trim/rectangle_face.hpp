#pragma once
// Internal: trimmed faces that are a rectangle of their surface's (u, v) domain. CAD files give
// many faces one trim loop that runs around the domain's border or around an iso-parametric part
// of it (a surface split along a knot line, e.g. the IEA blade's suction and pressure sides, most
// of the bearing's faces). Such a face is that rectangle of the surface, untrimmed: PreparedModel
// projects it as one (no region tests, no trim-edge pieces, the untrimmed certificates and reach
// bounds), with the same (u, v) and the same entity.

#include <optional>

#include "nurbsreg/engine/nurbs_surface.hpp"

namespace nurbsreg::engine {

struct UvRectangle {
  ParamInterval u, v;
};

// The rectangle, within the surface's domain, that the face's trim loops cut out, or nothing when
// they cut out anything else. It is one when there is a single loop, every uv curve of it lies
// on one side of the loop's bounding rectangle (all its control points on that side's line: the
// curve is in their convex hull), and the loop winds once around that rectangle (its signed area,
// the integral of u dv, exact from the curves' end points on the vertical sides, is the
// rectangle's). A curve on a closed path along the rectangle's border cannot wind a second time
// without covering twice the area, nor leave out a part of it. "On the line" allows 1e-12 of the
// rectangle's width: CAD files write a side's u as the same decimal, but a conversion may change
// its last bit; the face then differs from the rectangle by a sliver below every tolerance of
// the projection.
std::optional<UvRectangle> rectangle_of_face(const NurbsSurface& surface);

}  // namespace nurbsreg::engine
