#pragma once
// One entry point for model files, by extension (case-insensitive):
//   .json          -> read_model (model_json.hpp), the project's own format;
//   .step, .stp    -> read_step (step_reader.hpp), B-spline face surfaces of a CAD file;
//   .iges, .igs    -> read_iges (iges_reader.hpp), type-128 surfaces of a CAD file.
// Anything else throws InputError naming the supported extensions. Thread-safe.

#include <string>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::io {

engine::Model read_model_file(const std::string& path);

}  // namespace nurbsreg::io
