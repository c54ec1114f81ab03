#pragma once
// One entry point for model files, by extension (case-insensitive):
//   .json          -> read_model_json (model_json.hpp), the project's own format;
//   .step, .stp, .iges, .igs -> read_cad_file (cad_import.hpp), every face of a CAD file,
//                     trimmed, via OpenCASCADE.
// Anything else throws InputError naming the supported extensions. Thread-safe.

#include <string>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::io {

engine::Model read_model_file(const std::string& path);

}  // namespace nurbsreg::io
