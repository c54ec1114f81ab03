#include "common.hpp"

#include <spdlog/spdlog.h>

#include <cstdlib>
#include <ctime>

#include "nurbsreg/io/features_cache.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/io/model_warnings.hpp"

namespace nurbsreg::cli {

std::unique_ptr<tbb::global_control> limit_threads(int threads) {
  if (threads < 0) throw UsageError("--threads: must be >= 0 (0 = all hardware threads)");
  if (threads == 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                               static_cast<std::size_t>(threads));
}

double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

namespace {
bool model_cache_disabled = false;  // the application's --no-cache, set before any load
}  // namespace

void disable_model_cache() {
  model_cache_disabled = true;
  // And for every reader of the caches' settings in this process (the service's model loading
  // reads only the environment): set before any command starts a thread.
  ::setenv("NURBSREG_NO_CACHE", "1", 1);
}

engine::Model load_model_file(const std::string& path) {
  io::ModelFileOptions options;
  if (model_cache_disabled) options.cache.enabled = false;
  engine::Model model = io::read_model_file(path, options);
  // Faces that were left out, or are only partly in the model, change every answer near them:
  // every command that loads the model says so (`info` lists the details).
  for (const std::string& warning : io::model_warnings(path, model))
    spdlog::warn("{}", warning);
  return model;
}

std::shared_ptr<const registration::ModelFeatures> load_features(
    const engine::PreparedModel& model, const registration::FeatureOptions& options) {
  io::FeaturesCacheSettings settings = io::FeaturesCacheSettings::from_environment();
  if (model_cache_disabled) settings.enabled = false;
  return io::load_model_features(model, options, settings);
}

std::shared_ptr<const registration::ModelFeatures> cached_features(
    const engine::PreparedModel& model, const registration::FeatureOptions& options) {
  io::FeaturesCacheSettings settings = io::FeaturesCacheSettings::from_environment();
  if (model_cache_disabled) settings.enabled = false;
  return io::cached_model_features(model, options, settings);
}

}  // namespace nurbsreg::cli
