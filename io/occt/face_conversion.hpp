#pragma once
// One OCCT face to an engine NurbsSurface with trim loops (the OpenCASCADE module: OCCT types).

#include <TopoDS_Face.hxx>
#include <optional>
#include <string>

#include "nurbsreg/engine/nurbs_surface.hpp"

namespace nurbsreg::io::cad_detail {

struct FaceConversion {
  std::optional<engine::NurbsSurface> surface;  // empty: failed, see `error`
  std::string error;
  std::string surface_type;  // OCCT type of the original surface, e.g. "Geom_Plane"
  bool analytic = false;     // the original surface was not a B-spline or Bezier surface
  int approximations = 0;
  int degenerated_edges = 0;
  int rebuilt_edges = 0;       // 3-D edges replaced by S(uv(t)) (the file's was off the face)
  int inconsistent_edges = 0;  // kept off by more than the tolerance (no approximation found)
  int uv_outside_domain = 0;   // uv curves leaving the surface's domain (S clamps there)
};

// Whether the face's surface is analytic (a plane, cylinder, ..., anything but a B-spline or
// Bézier surface): such faces need OCCT's NURBS conversion. False for a face without surface.
bool is_analytic(const TopoDS_Face& face);

// Converts `face` (as found in the shape, with its location and orientation). `nurbs_face`,
// when given, is the face after BRepBuilderAPI_NurbsConvert of a shape that holds it (used for
// analytic faces; without it they are converted one by one). `tolerance` is the absolute 3-D
// error allowed for approximations. Never throws.
FaceConversion convert_face(const TopoDS_Face& face, const TopoDS_Face* nurbs_face,
                            double tolerance);

}  // namespace nurbsreg::io::cad_detail
