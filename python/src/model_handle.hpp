#pragma once
// A loaded model as Python holds it: the prepared model (built once, immutable, shared by every
// call and by the Aligners made from it), a pool of Projectors, so that project() calls from
// several Python threads at once each get their own (one call at a time per Projector) and keep
// its per-thread scratch for later calls, and the global alignment's model features, read from
// the features cache or built once per loaded model (as `nurbsreg align` and the service get
// them), for every Aligner made from it: `nurbsreg.align(model, scan)` makes a new Aligner per
// call, and building the features costs more than the alignment on a real part.

#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/io/features_cache.hpp"
#include "nurbsreg/registration/model_features.hpp"

namespace nurbsreg::python {

class ModelHandle {
 public:
  ModelHandle(std::string path, engine::Model model)
      : path_(std::move(path)), model_(model), prepared_(std::move(model)) {}

  const std::string& path() const { return path_; }
  const engine::PreparedModel& prepared() const { return prepared_; }
  // The model as the file gave it (info, warnings): the prepared one may hold some faces in
  // another form (engine::PreparedModel::rectangle_face).
  const engine::Model& model() const { return model_; }

  // A Projector for one call, returned to the pool when the lease ends. Thread-safe.
  class Lease {
   public:
    Lease(ModelHandle& owner, std::unique_ptr<engine::Projector> projector)
        : owner_(owner), projector_(std::move(projector)) {}
    ~Lease() { owner_.give_back(std::move(projector_)); }
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    engine::Projector& operator*() const { return *projector_; }

   private:
    ModelHandle& owner_;
    std::unique_ptr<engine::Projector> projector_;
  };
  // The model's features for `options` (io::load_model_features: the features cache's settings
  // from the environment, NURBSREG_NO_CACHE turns it off). Thread-safe; a second caller with the
  // same options waits for the first one's build and shares it. Throws what the build throws
  // (std::runtime_error: a model without area).
  std::shared_ptr<const registration::ModelFeatures> features(
      const registration::FeatureOptions& options) {
    std::lock_guard lock(features_mutex_);
    for (const auto& [o, f] : features_) {
      if (o == options) return f;
    }
    auto f =
        io::load_model_features(prepared_, options, io::FeaturesCacheSettings::from_environment());
    features_.emplace_back(options, f);
    return f;
  }

  Lease lease_projector() {
    std::lock_guard lock(mutex_);
    if (idle_.empty()) return Lease(*this, std::make_unique<engine::Projector>(prepared_));
    std::unique_ptr<engine::Projector> p = std::move(idle_.back());
    idle_.pop_back();
    return Lease(*this, std::move(p));
  }

 private:
  void give_back(std::unique_ptr<engine::Projector> projector) {
    std::lock_guard lock(mutex_);
    idle_.push_back(std::move(projector));
  }

  std::string path_;
  const engine::Model model_;
  const engine::PreparedModel prepared_;
  std::mutex mutex_;
  std::vector<std::unique_ptr<engine::Projector>> idle_;
  std::mutex features_mutex_;
  std::vector<
      std::pair<registration::FeatureOptions, std::shared_ptr<const registration::ModelFeatures>>>
      features_;
};

using ModelPtr = std::shared_ptr<ModelHandle>;

}  // namespace nurbsreg::python
