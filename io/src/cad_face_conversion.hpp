#pragma once
// One OCCT face to an engine NurbsSurface with trim loops (private to io: OCCT types).

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
};

// Converts `face` (as found in the shape, with its location and orientation). `tolerance` is
// the absolute 3-D error allowed for approximations (degree reduction). Never throws.
FaceConversion convert_face(const TopoDS_Face& face, double tolerance);

}  // namespace nurbsreg::io::cad_detail
