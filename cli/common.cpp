#include "common.hpp"

#include "nurbsreg/io/model_file.hpp"

namespace nurbsreg::cli {

std::unique_ptr<tbb::global_control> limit_threads(int threads) {
  if (threads < 0) throw UsageError("--threads: must be >= 0 (0 = all hardware threads)");
  if (threads == 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                               static_cast<std::size_t>(threads));
}

engine::Model load_model_file(const std::string& path) {
  return io::read_model_file(path);
}

}  // namespace nurbsreg::cli
