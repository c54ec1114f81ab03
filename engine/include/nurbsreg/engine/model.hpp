#pragma once
// A model: named NURBS surfaces and curves in one unit system, as loaded from a file.

#include <optional>
#include <string>
#include <vector>

#include "nurbsreg/engine/nurbs_curve.hpp"
#include "nurbsreg/engine/nurbs_surface.hpp"

namespace nurbsreg::engine {

struct Model {
  std::string units = "mm";
  std::vector<NurbsSurface> surfaces;
  std::vector<NurbsCurve> curves;

  // An error naming the entity and the field, e.g.
  // `surface 2 "hood": weights[1][3]: must be > 0 (got -1)`, or nothing.
  std::optional<std::string> validate() const;
};

}  // namespace nurbsreg::engine
