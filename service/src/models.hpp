#pragma once
// The prepared models of a service and their pools of per-frame workers (private to service/).
//
// A ServedModel is immutable once added (its PreparedModel is shared by every request); the
// pools hold Aligners (the service's default ICP options) and Projectors that finished a frame,
// so the next frame reuses their buffers instead of allocating them again. A pool never holds
// more objects than frames ran at once (bounded by --max-inflight).

#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/registration/alignment.hpp"

namespace nurbsreg::service::detail {

struct ServedModel {
  std::string id;
  std::string file;
  std::size_t surfaces = 0;
  std::size_t curves = 0;
  std::size_t skipped_faces = 0;
  std::size_t patches = 0;
  double prepare_seconds = 0.0;
  double features_seconds = 0.0;
  std::unique_ptr<const engine::PreparedModel> prepared;
  // The global stage's model data (keypoints, descriptors), built once when the model is
  // served and shared by every aligner over it (pooled and per session), so no request pays
  // for it. Null for a model without surface area (its aligners then fail with that reason).
  std::shared_ptr<const registration::ModelFeatures> features;

  // A new aligner over this model (the shared features) with `options`.
  std::unique_ptr<registration::Aligner> make_aligner(const icp::IcpOptions& options) const;
  std::unique_ptr<registration::Aligner> take_aligner(const icp::IcpOptions& defaults);
  void give_back(std::unique_ptr<registration::Aligner> aligner);
  std::unique_ptr<engine::Projector> take_projector();
  void give_back(std::unique_ptr<engine::Projector> projector);

 private:
  std::mutex mutex_;
  std::vector<std::unique_ptr<registration::Aligner>> aligners_;
  std::vector<std::unique_ptr<engine::Projector>> projectors_;
};

// Prepares a model read from `file` (what GET /v1/models shows); `id` empty: the file's stem.
std::shared_ptr<ServedModel> serve_model(engine::Model model, const std::string& file,
                                         std::string id);

class ModelRegistry {
 public:
  // Throws std::invalid_argument when the id is taken.
  void add(std::shared_ptr<ServedModel> model);
  std::shared_ptr<ServedModel> find(const std::string& id) const;
  std::vector<std::shared_ptr<ServedModel>> list() const;
  std::size_t size() const;

 private:
  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<ServedModel>> models_;
};

}  // namespace nurbsreg::service::detail
