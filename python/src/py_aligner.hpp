#pragma once
// The Python Aligner: one registration::Aligner over a loaded model, kept from call to call so
// frame after frame reuses its warm state (per-point arrays, projection hints, the model's
// coarse-stage features), as the C++ API allows. align() and inspect() both run through it.

#include <pybind11/pybind11.h>

#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "alignment_frame.hpp"
#include "bindings.hpp"
#include "model_handle.hpp"
#include "nurbsreg/registration/alignment.hpp"
#include "points_arg.hpp"
#include "released_call.hpp"

namespace nurbsreg::python {

class PyAligner {
 public:
  PyAligner(ModelPtr model, icp::IcpOptions options, registration::RegistrationOptions registration)
      : model_(std::move(model)), options_(std::move(options)), registration_(registration) {
    if (model_->model().surfaces.empty()) {
      throw py::value_error(model_->path() + ": align needs a model with surfaces");
    }
    aligner_ = make_aligner();
  }

  // `after` (may be empty) runs right after the alignment, without the GIL and before the next
  // align() may start: for what reads the aligner's last projections (inspect()).
  using After = std::function<void(const registration::Aligner&, AlignmentFrame&)>;
  AlignmentFramePtr align(const py::handle& scan_object, const py::object& init_object,
                          const std::string& global, bool distances,
                          const std::optional<int>& threads, const After& after = {}) {
    const auto start = std::chrono::steady_clock::now();
    const PointsArg scan(scan_object, "scan");
    registration::AlignRequest request = make_request(init_object, global);
    // Per-point exact projections only for what reads them: the distances, and `after`.
    request.all_projections = distances || static_cast<bool>(after);
    const int thread_limit = thread_count(threads);
    auto frame = std::make_shared<AlignmentFrame>();
    frame->method = options_.method;
    frame->max_iterations = options_.max_iterations;
    frame->has_distances = distances;
    {
      py::gil_scoped_release release;
      const std::lock_guard lock(mutex_);  // one align() at a time per Aligner
      py::gil_scoped_acquire gil;
      try {
        run_released(thread_limit, scan.size() >= kWatchedPoints, [&] {
          // From any pose the alignment needs all of the model's features: the loaded model's
          // (once per model, from the features cache), kept by this Aligner from then on.
          if (request.runs_global() && !features_) {
            features_ = model_->features(registration_.global.features);
            aligner_ = make_aligner();
          }
          align_rows(*aligner_, scan, request, *frame);
          if (after && frame->rows > frame->skipped) after(*aligner_, *frame);
        });
      } catch (py::error_already_set&) {
        // Ctrl-C: the cancelled run may have left the warm state half written. Start afresh.
        aligner_ = make_aligner();
        throw;
      }
    }
    if (frame->rows == frame->skipped) {
      throw py::value_error("scan: no finite points to align (" + std::to_string(frame->skipped) +
                            " skipped)");
    }
    if (!frame->result.failure) add_warnings(*frame);
    frame->seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return frame;
  }

  const ModelPtr& model() const { return model_; }
  const icp::IcpOptions& options() const { return options_; }

 private:
  std::unique_ptr<registration::Aligner> make_aligner() const {
    return std::make_unique<registration::Aligner>(model_->prepared(), options_, registration_,
                                                   features_);
  }

  ModelPtr model_;
  icp::IcpOptions options_;
  registration::RegistrationOptions registration_;
  std::mutex mutex_;
  std::shared_ptr<const registration::ModelFeatures> features_;  // the model's, once shared
  std::unique_ptr<registration::Aligner> aligner_;
};

}  // namespace nurbsreg::python
