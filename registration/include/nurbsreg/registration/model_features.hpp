#pragma once
// What the global coarse alignment needs of a model, computed once per prepared model and
// shared by every Aligner over it (`batch` runs one Aligner per worker; the service one per
// session): area-uniform samples with the engine's exact normals, thinned to one per voxel,
// and their descriptors (features.hpp in src: a sign-invariant FPFH variant).
//
// The voxel (the sample spacing, model units) comes from the model's surface area, so the
// scan, voxelised with the same side, has the same density as the samples whatever its size
// (a partial view, a scene with clutter).
//
// Built lazily and thread-safe: the constructor only measures the area; keypoints() and
// descriptors() build on first use (std::call_once), then every call returns the same const
// data. Deterministic (fixed seed, results written by index).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::registration {

struct FeatureOptions {
  // Keypoints aimed at on the whole model (one per voxel); more: finer features, slower.
  std::size_t keypoints = 5000;
  // Neighbourhood radii in voxels: normals of the scan (PCA), descriptors.
  double normal_radius = 2.0;
  double feature_radius = 8.0;
  std::uint64_t seed = 1;
};

struct ModelKeypoints {
  std::vector<engine::Vec3> points;
  std::vector<engine::Vec3> normals;  // exact, on the face's outer side
};

class ModelFeatures {
 public:
  // `model` must outlive this object. Throws std::runtime_error when the model has no surface
  // area to sample (no surfaces, empty trimmed faces).
  explicit ModelFeatures(const engine::PreparedModel& model, FeatureOptions options = {});
  ModelFeatures(const engine::PreparedModel&& model, FeatureOptions options = {}) = delete;

  const FeatureOptions& options() const { return options_; }
  double surface_area() const { return area_; }
  // Sample spacing (model units): sqrt(area / keypoints).
  double voxel() const { return voxel_; }
  const ModelKeypoints& keypoints() const;
  // Row i describes keypoints().points[i]; row-major float, 32 columns.
  const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& descriptors() const;
  // The model's discrete rotational symmetries (model frame, identity excluded): turns that map
  // the model onto itself, checked by exact distances (model_symmetry.hpp in src). A scan of a
  // symmetric part fits as well in every pose S * T as in T; the coarse report lists them.
  const std::vector<Eigen::Isometry3d>& symmetries() const;

 private:
  const engine::PreparedModel& model_;
  FeatureOptions options_;
  double area_ = 0.0;
  double voxel_ = 0.0;
  mutable std::once_flag keypoints_once_, descriptors_once_, symmetries_once_;
  mutable ModelKeypoints keypoints_;
  mutable Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> descriptors_;
  mutable std::vector<Eigen::Isometry3d> symmetries_;
};

}  // namespace nurbsreg::registration
