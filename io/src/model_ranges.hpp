#pragma once
// Load-time checks of a valid model against what the projection can represent and what one
// model may cost (private to io; called by parse_model, so every model reader applies them,
// JSON and CAD alike).

#include <string>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::io::detail {

// Throws InputError naming the entity and the field when a coordinate, knot, knot span or
// weight is outside the ranges of input_ranges.hpp.
void check_model_ranges(const engine::Model& model, const std::string& file);

// Throws InputError when the model's Bézier decomposition (patches and curve pieces, counted
// from the knot vectors without building them) holds more control points than
// resource_limits().max_bezier_points.
void check_model_size(const engine::Model& model, const std::string& file);

}  // namespace nurbsreg::io::detail
