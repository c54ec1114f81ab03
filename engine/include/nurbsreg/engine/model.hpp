#pragma once
// A model: named NURBS surfaces and curves in one unit system, as loaded from a file.

#include <optional>
#include <string>
#include <vector>

#include "nurbsreg/engine/nurbs_curve.hpp"
#include "nurbsreg/engine/nurbs_surface.hpp"

namespace nurbsreg::engine {

// A face of a CAD file that could not be converted: never dropped silently.
struct SkippedFace {
  int face = -1;  // 0-based index of the face in the file's face order
  std::string reason;
};

struct Model {
  std::string units = "mm";
  std::vector<NurbsSurface> surfaces;
  std::vector<NurbsCurve> curves;
  // Faces of the source file that are not in `surfaces` (CAD import), with the reason.
  std::vector<SkippedFace> skipped_faces;

  // An error naming the entity and the field, e.g.
  // `surface 2 "hood": weights[1][3]: must be > 0 (got -1)`, or nothing.
  std::optional<std::string> validate() const;
};

}  // namespace nurbsreg::engine
