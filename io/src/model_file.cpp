#include "nurbsreg/io/model_file.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "nurbsreg/io/cad_import.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_json.hpp"

namespace nurbsreg::io {

engine::Model read_model_file(const std::string& path, const ModelFileOptions& options) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  if (ext == ".json") return read_model_json(path);
  if (ext == ".step" || ext == ".stp" || ext == ".iges" || ext == ".igs")
    return read_model_through_cache(path, options.cache,
                                    [](const std::string& p) { return read_cad_file(p); });
  throw InputError(path, "unknown model format: expected a .json, .step, .stp, .iges or .igs file");
}

}  // namespace nurbsreg::io
