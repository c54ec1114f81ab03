#pragma once
// What every front end (the CLI's commands, the Python package) warns about a loaded model:
// faces of a CAD file that could not be converted (they are not in the model), and faces whose
// trim loops leave their surface's parameter domain by more than 1e-4 of its width (that part of
// the face is missing, so points near it may get a farther closest point). One line each,
// starting with `label` (the file). Thread-safe; allocates (load-time code).

#include <string>
#include <vector>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::io {

std::vector<std::string> model_warnings(const std::string& label, const engine::Model& model);

}  // namespace nurbsreg::io
