// The global alignment's model features. A change to what any function here (or the
// sampling, descriptors and symmetry search it calls) computes changes the parts a cache stores:
// bump kModelFeaturesRevision (model_features.hpp) with it, or cached features go stale unseen.
#include "nurbsreg/registration/model_features.hpp"

#include <spdlog/spdlog.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "features.hpp"
#include "model_symmetry.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "point_grid.hpp"

namespace nurbsreg::registration {
namespace {

// Runs `build` in its own isolated TBB context: the features are a cache shared by every later
// alignment, so a caller's cancellation (Ctrl-C in Python cancels the caller's task group) must
// not cut their parallel loops short and leave a partial cache behind.
template <class Build>
void build_isolated(Build&& build) {
  tbb::task_group_context own(tbb::task_group_context::isolated);
  tbb::task_group group(own);
  group.run_and_wait(std::forward<Build>(build));
}

static_assert(kFeatureDescriptorSize == detail::kDescriptorSize);

double voxel_of(double area, const FeatureOptions& options) {
  return std::sqrt(area / static_cast<double>(std::max<std::size_t>(options.keypoints, 16)));
}

void check_model(const engine::PreparedModel& model) {
  if (model.model().surfaces.empty()) {
    throw std::runtime_error("the model has no surfaces to align a scan to");
  }
}

bool finite(const engine::Vec3& v) {
  return v.allFinite();
}

[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("stored model features: " + what);
}

// The keypoints the descriptors describe (ModelFeatures::described_keypoints), computed again
// from stored keypoints (a few milliseconds): isolated like the builds, so that a caller's
// cancellation cannot cut it short while a cache entry is read.
ModelKeypoints described_of(const ModelKeypoints& k, const FeatureOptions& options, double voxel) {
  ModelKeypoints out;
  build_isolated([&] { out = detail::surface_points(k.points, options.normal_radius * voxel); });
  return out;
}

// The checks from_parts promises of the descriptors, given the keypoints they describe.
void check_descriptors(const ModelFeatureParts& p, std::size_t described) {
  const std::size_t n = p.keypoints.points.size();
  if (static_cast<std::size_t>(p.descriptors.rows()) != described ||
      p.descriptors.cols() != kFeatureDescriptorSize) {
    fail(std::to_string(p.descriptors.rows()) + " x " + std::to_string(p.descriptors.cols()) +
         " descriptors for " + std::to_string(described) + " described keypoints of " +
         std::to_string(n) + " (one row of " + std::to_string(kFeatureDescriptorSize) + " each)");
  }
  if (!p.descriptors.allFinite()) fail("a descriptor is not finite");
}

// check_model for the stored parts' factories: their errors are std::invalid_argument.
void check_model_argument(const engine::PreparedModel& model) {
  try {
    check_model(model);
  } catch (const std::runtime_error& e) {
    throw std::invalid_argument(e.what());
  }
}

// The checks from_parts promises (model_features.hpp), each naming the part.
void check_parts(const ModelFeatureParts& p, const FeatureOptions& options,
                 const engine::PreparedModel& model) {
  if (!(p.surface_area > 0.0) || !std::isfinite(p.surface_area)) {
    fail("surface area " + std::to_string(p.surface_area) + " is not finite and positive");
  }
  if (p.voxel != voxel_of(p.surface_area, options)) {
    fail("the voxel is not the one the surface area gives with " +
         std::to_string(options.keypoints) + " keypoints");
  }
  const std::size_t n = p.keypoints.points.size();
  if (p.keypoints.normals.size() != n) {
    fail(std::to_string(n) + " keypoints but " + std::to_string(p.keypoints.normals.size()) +
         " normals");
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!finite(p.keypoints.points[i]) || !finite(p.keypoints.normals[i])) {
      fail("keypoint " + std::to_string(i) + " is not finite");
    }
  }
  // Keypoints are samples of the model's faces: inside its box (with a margin for the rounding
  // of an evaluation). Anything else is not this model's (and far points would overflow the
  // grids' cell indices).
  const engine::Aabb& box = model.bounds();
  const double margin = 1e-6 * box.diagonal();
  for (std::size_t i = 0; i < n; ++i) {
    if (box.squared_distance(p.keypoints.points[i]) > margin * margin) {
      fail("keypoint " + std::to_string(i) + " lies outside the model's bounding box");
    }
  }
  for (std::size_t i = 0; i < p.symmetries.size(); ++i) {
    if (!p.symmetries[i].matrix().allFinite()) {
      fail("symmetry " + std::to_string(i) + " is not finite");
    }
  }
}

}  // namespace

ModelFeatures::ModelFeatures(const engine::PreparedModel& model, FeatureOptions options)
    : model_(model), options_(options) {
  check_model(model);
  area_ = engine::surface_area(model.model());
  if (!(area_ > 0.0) || !std::isfinite(area_)) {
    throw std::runtime_error("the model's surfaces have no area to align a scan to");
  }
  voxel_ = voxel_of(area_, options_);
}

ModelFeatures::ModelFeatures(FromParts, const engine::PreparedModel& model, FeatureOptions options,
                             ModelFeatureParts parts, ModelKeypoints described)
    : model_(model),
      options_(options),
      area_(parts.surface_area),
      voxel_(parts.voxel),
      keypoints_(std::move(parts.keypoints)),
      descriptors_(std::move(parts.descriptors)),
      symmetries_(std::move(parts.symmetries)) {
  // Every part is there: the lazy builds must never run (they would overwrite them).
  std::call_once(keypoints_once_, [] {});
  std::call_once(described_once_, [&] { described_ = std::move(described); });
  std::call_once(descriptors_once_, [] {});
  std::call_once(symmetries_once_, [] {});
}

std::shared_ptr<const ModelFeatures> ModelFeatures::from_parts(const engine::PreparedModel& model,
                                                               FeatureOptions options,
                                                               ModelFeatureParts parts) {
  check_model_argument(model);
  check_parts(parts, options, model);
  ModelKeypoints described = described_of(parts.keypoints, options, parts.voxel);
  check_descriptors(parts, described.points.size());
  // Not make_shared: the constructor is private.
  return std::shared_ptr<const ModelFeatures>(
      new ModelFeatures(FromParts{}, model, options, std::move(parts), std::move(described)));
}

ModelFeatures::ModelFeatures(FromSamples, const engine::PreparedModel& model,
                             FeatureOptions options, ModelFeatureParts parts)
    : model_(model),
      options_(options),
      area_(parts.surface_area),
      voxel_(parts.voxel),
      keypoints_(std::move(parts.keypoints)) {
  // The keypoints are there: their build must never run (it would overwrite them). The rest
  // is built from them on first use.
  std::call_once(keypoints_once_, [] {});
}

std::shared_ptr<const ModelFeatures> ModelFeatures::from_samples(const engine::PreparedModel& model,
                                                                 FeatureOptions options,
                                                                 ModelFeatureParts parts) {
  check_model_argument(model);
  if (parts.descriptors.size() != 0 || !parts.symmetries.empty()) {
    fail("descriptors or symmetries given with the samples alone");
  }
  check_parts(parts, options, model);
  return std::shared_ptr<const ModelFeatures>(
      new ModelFeatures(FromSamples{}, model, options, std::move(parts)));
}

void ModelFeatures::build_all() const {
  descriptors();  // and the keypoints
  symmetries();
}

const ModelKeypoints& ModelFeatures::keypoints() const {
  std::call_once(keypoints_once_, [&] {
    build_isolated([&] {
      // Four draws per voxel, then the draw nearest each voxel's centroid: samples spread like the
      // voxelised scan's points (a plain random draw clumps), each with its exact normal.
      const std::vector<engine::SurfaceSample> samples =
          engine::sample_surfaces(model_.model(), 4 * options_.keypoints, options_.seed);
      std::vector<engine::Vec3> points(samples.size());
      for (std::size_t i = 0; i < samples.size(); ++i)
        points[i] = samples[i].point;
      const detail::Voxelised v = detail::voxelise(points, voxel_);
      keypoints_.points.reserve(v.nearest.size());
      keypoints_.normals.reserve(v.nearest.size());
      for (std::uint32_t i : v.nearest) {
        keypoints_.points.push_back(samples[i].point);
        keypoints_.normals.push_back(samples[i].normal);
      }
    });
  });
  return keypoints_;
}

const ModelKeypoints& ModelFeatures::described_keypoints() const {
  std::call_once(described_once_,
                 [&] { described_ = described_of(keypoints(), options_, voxel_); });
  return described_;
}

const FeatureDescriptors& ModelFeatures::descriptors() const {
  std::call_once(descriptors_once_, [&] {
    build_isolated([&] {
      const ModelKeypoints& k = described_keypoints();
      const double radius = options_.feature_radius * voxel_;
      const detail::PointGrid grid(k.points, radius);
      descriptors_ = detail::describe(k.points, k.normals, grid, radius);
    });
  });
  return descriptors_;
}

const std::vector<Eigen::Isometry3d>& ModelFeatures::symmetries() const {
  std::call_once(symmetries_once_, [&] {
    const auto start = std::chrono::steady_clock::now();
    build_isolated(
        [&] { symmetries_ = detail::find_model_symmetries(model_, keypoints(), voxel_); });
    spdlog::debug("model symmetries: {} discrete turn(s) in {:.3f} s", symmetries_.size(),
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  });
  return symmetries_;
}

}  // namespace nurbsreg::registration
