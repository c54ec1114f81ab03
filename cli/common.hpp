#pragma once
// Helpers shared by the sub-commands: usage errors, thread limits, model loading, timing.

#include <tbb/global_control.h>

#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>

#include "nurbsreg/engine/model.hpp"
#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/registration/model_features.hpp"

namespace nurbsreg::cli {

// A semantic usage error found after parsing (e.g. a malformed --pose value): exit status 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Some frames of a batch failed while the others were processed: exit status 4 (README
// "Batch jobs"). The message says how many and where the summary is.
class FramesFailed : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Limits TBB to `threads` workers for the lifetime of the returned object (0 = all hardware
// threads). The thread count belongs to the application, never to the library.
std::unique_ptr<tbb::global_control> limit_threads(int threads);

// Reads a model file (JSON; CAD formats when supported), throwing io::InputError naming the file.
// STEP/IGES files go through the model cache (io/model_cache.hpp) unless disabled.
engine::Model load_model_file(const std::string& path);
// The global alignment's model features through the features cache (io/features_cache.hpp),
// built in full and stored on a miss; without a cache (--no-cache, NURBSREG_NO_CACHE) built
// lazily as the aligner would. For the runs that align from any pose (the others only need the
// area). Errors of building (a model without area: std::runtime_error) pass through.
std::shared_ptr<const registration::ModelFeatures> load_features(
    const engine::PreparedModel& model, const registration::FeatureOptions& options);
// For the runs from a given pose: the area and keypoints from the features cache when an entry
// is there (io::cached_model_features), else measured now; never builds the rest or stores.
std::shared_ptr<const registration::ModelFeatures> cached_features(
    const engine::PreparedModel& model, const registration::FeatureOptions& options);
// --no-cache: load_model_file converts CAD files every time and load_features builds the
// features every time (called once, from main).
void disable_model_cache();

// This process's CPU seconds (all threads), for the timings beside the wall times.
double process_cpu_seconds();

class Stopwatch {
 public:
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

}  // namespace nurbsreg::cli
