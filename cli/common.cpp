#include "common.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_json.hpp"

namespace nurbsreg::cli {

std::unique_ptr<tbb::global_control> limit_threads(int threads) {
  if (threads < 0) throw UsageError("--threads: must be >= 0 (0 = all hardware threads)");
  if (threads == 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                               static_cast<std::size_t>(threads));
}

engine::Model load_model_file(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".json") return io::read_model(path);
  throw io::InputError(path, "unsupported model format '" + extension +
                                 "' (supported: .json as described in CONTRACT.md)");
}

}  // namespace nurbsreg::cli
