#pragma once
// Internal to registration: the global coarse stage as a whole (global_alignment.cpp), what
// Aligner::align(scan) runs before its fine ICP.

#include <chrono>
#include <optional>
#include <span>
#include <string>

#include "nurbsreg/engine/types.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/registration/global.hpp"
#include "nurbsreg/registration/model_features.hpp"

namespace nurbsreg::registration::detail {

struct CoarseOutcome {
  CoarseReport report;
  // Why no pose came out (too few points for features, no hypothesis, the deadline); empty
  // otherwise.
  std::optional<std::string> failure;
  bool timed_out = false;  // the failure is the deadline's
  bool cancelled = false;  // ... or the caller's cancellation
  // The stage ran to its end and found no pose (neither of the two above).
  bool found_nothing() const { return failure && !timed_out && !cancelled; }
};

// CPU seconds of this process so far (all its threads).
double process_cpu_seconds();

// Keypoints and descriptors of the scan, matches against the model's, sample consensus, and
// every kept hypothesis refined by a short exact ICP on a seeded subsample (through `finder`,
// which is reset) and scored by exact distances within a tolerance from `noise`. The winner is
// report.winner. Deterministic for options.seed, the same for any thread count. `deadline` is
// checked between the steps and before every hypothesis's verification (and by its ICP).
CoarseOutcome coarse_align(
    std::span<const engine::Vec3> scan, const ModelFeatures& features, const GlobalOptions& options,
    double noise, icp::ModelCorrespondenceFinder& finder,
    std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max());

}  // namespace nurbsreg::registration::detail
