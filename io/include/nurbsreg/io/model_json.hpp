#pragma once
// Models as JSON (`*.json`, CONTRACT.md §2 "Model"):
//
//   { "nurbsreg_model": 1, "units": "mm",
//     "surfaces": [ { "name", "degree": [p, q], "knots_u", "knots_v",
//                     "control_points": count_u rows of count_v [x, y, z],
//                     "weights": same nesting, optional } ],
//     "curves":   [ { "name", "degree", "knots", "control_points": [[x, y(, z)]...],
//                     "weights": optional } ] }
//
// Reading checks the document's shape (types, nesting, counts derived from the knot vectors)
// and then runs engine::Model::validate(), so every accepted model is valid for the engine.
// Any problem throws InputError whose message names the file and, for syntax errors, the line
// and column, otherwise the entity and field:
//   `hood.json: surface 0 "hood": control_points[2][1]: expected 3 numbers [x, y, z], got 2`.
// Unknown keys are ignored, so files written by later versions that only add fields still load.
//
// Writing emits the same format with every number in its shortest exact round-trip form
// (std::to_chars), so write -> read reproduces the model bit for bit. Files are written
// atomically (see atomic_file.hpp). All functions are thread-safe (no shared state) and allocate
// freely: they are load-time code, not hot paths.

#include <string>
#include <string_view>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::io {

// The format version this build reads and writes (`"nurbsreg_model": 1`).
inline constexpr int kModelFormatVersion = 1;

// Reads and validates a model in the project's JSON format (read_model_file, model_file.hpp,
// reads every supported format). Throws InputError (unreadable, malformed or invalid).
engine::Model read_model_json(const std::string& path);

// Parses a model from JSON text; `file_label` is the name used in error messages.
engine::Model parse_model(std::string_view text, const std::string& file_label);

// The model as JSON text (control points one u-row per line). Does not validate.
std::string model_to_json(const engine::Model& model);

// Writes model_to_json(model) atomically. Throws OutputError when the file cannot be written.
void write_model(const std::string& path, const engine::Model& model);

}  // namespace nurbsreg::io
