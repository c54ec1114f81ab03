#include "models.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>
#include <stdexcept>

#include "nurbsreg/io/features_cache.hpp"

namespace nurbsreg::service::detail {

std::unique_ptr<registration::Aligner> ServedModel::make_aligner(
    const icp::IcpOptions& options) const {
  return std::make_unique<registration::Aligner>(*prepared, options,
                                                 registration::RegistrationOptions{}, features);
}

std::unique_ptr<registration::Aligner> ServedModel::take_aligner(const icp::IcpOptions& defaults) {
  {
    std::lock_guard lock(mutex_);
    if (!aligners_.empty()) {
      auto aligner = std::move(aligners_.back());
      aligners_.pop_back();
      return aligner;
    }
  }
  return make_aligner(defaults);
}

void ServedModel::give_back(std::unique_ptr<registration::Aligner> aligner) {
  std::lock_guard lock(mutex_);
  aligners_.push_back(std::move(aligner));
}

std::unique_ptr<engine::Projector> ServedModel::take_projector() {
  {
    std::lock_guard lock(mutex_);
    if (!projectors_.empty()) {
      auto projector = std::move(projectors_.back());
      projectors_.pop_back();
      return projector;
    }
  }
  return std::make_unique<engine::Projector>(*prepared);
}

void ServedModel::give_back(std::unique_ptr<engine::Projector> projector) {
  std::lock_guard lock(mutex_);
  projectors_.push_back(std::move(projector));
}

std::shared_ptr<ServedModel> serve_model(engine::Model model, const std::string& file,
                                         std::string id) {
  auto served = std::make_shared<ServedModel>();
  served->id = id.empty() ? std::filesystem::path(file).stem().string() : std::move(id);
  served->file = file;
  served->surfaces = model.surfaces.size();
  served->curves = model.curves.size();
  served->skipped_faces = model.skipped_faces.size();
  const auto start = std::chrono::steady_clock::now();
  served->prepared = std::make_unique<const engine::PreparedModel>(std::move(model));
  served->prepare_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  served->patches = served->prepared->patch_count();
  if (served->surfaces > 0) {
    const auto features_start = std::chrono::steady_clock::now();
    try {
      // The options every served aligner uses (RegistrationOptions{}), built now in full, or
      // read from the features cache (io/features_cache.hpp, the model cache's settings).
      auto features = io::load_model_features(*served->prepared,
                                              registration::RegistrationOptions{}.global.features,
                                              io::FeaturesCacheSettings::from_environment());
      features->build_all();
      served->features = std::move(features);
    } catch (const std::runtime_error& e) {
      spdlog::warn("{}: no features for the global alignment: {}", file, e.what());
    }
    served->features_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - features_start).count();
  }
  return served;
}

void ModelRegistry::add(std::shared_ptr<ServedModel> model) {
  std::lock_guard lock(mutex_);
  const std::string id = model->id;
  if (!models_.emplace(id, std::move(model)).second) {
    throw std::invalid_argument("a model with id \"" + id + "\" is already loaded");
  }
}

std::shared_ptr<ServedModel> ModelRegistry::find(const std::string& id) const {
  std::lock_guard lock(mutex_);
  const auto it = models_.find(id);
  return it == models_.end() ? nullptr : it->second;
}

std::vector<std::shared_ptr<ServedModel>> ModelRegistry::list() const {
  std::lock_guard lock(mutex_);
  std::vector<std::shared_ptr<ServedModel>> out;
  for (const auto& [id, model] : models_)
    out.push_back(model);
  return out;
}

std::size_t ModelRegistry::size() const {
  std::lock_guard lock(mutex_);
  return models_.size();
}

}  // namespace nurbsreg::service::detail
