#pragma once
// One entry point for model files, by extension (case-insensitive):
//   .json          -> read_model_json (model_json.hpp), the project's own format;
//   .step, .stp, .iges, .igs -> read_cad_file (cad_import.hpp), every face of a CAD file,
//                     trimmed, via OpenCASCADE.
// Anything else throws InputError naming the supported extensions. Thread-safe.
// STEP/IGES files go through the converted-model cache (model_cache.hpp), on by default.

#include <string>

#include "nurbsreg/engine/model.hpp"
#include "nurbsreg/io/model_cache.hpp"

namespace nurbsreg::io {

struct ModelFileOptions {
  ModelCacheSettings cache = ModelCacheSettings::from_environment();
};

engine::Model read_model_file(const std::string& path, const ModelFileOptions& options = {});

}  // namespace nurbsreg::io
