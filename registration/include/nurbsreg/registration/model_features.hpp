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
//
// Stored: build_all() builds every part now, and from_parts() makes the object back from those
// parts without building anything (io/features_cache.hpp keeps them on disk between runs; the
// same parts give the same alignments to the bit). from_samples() does the same with the area
// and keypoints alone, which is what an alignment from a given pose needs.

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
  bool operator==(const FeatureOptions&) const = default;
};

struct ModelKeypoints {
  std::vector<engine::Vec3> points;
  std::vector<engine::Vec3> normals;  // keypoints(): exact, outward; described: by PCA, unsigned
};

// The revision of what ModelFeatures computes from a model and FeatureOptions: the surface area
// (engine::surface_area), the keypoints (engine::sample_surfaces and the voxel thinning), the
// descriptors (features.cpp, point_grid.cpp) and the symmetries (model_symmetry.cpp). Stored
// features (io/features_cache.hpp) of another revision are stale and built again. The cache's
// key also holds a digest of the sources that compute the parts (io/CMakeLists.txt lists them),
// so an edit there needs no bump; bump it when a change elsewhere (the engine's evaluation, say)
// changes a single bit of the parts, or a cache would keep serving the old ones.
// 2: the descriptors describe the keypoints PCA finds on a surface, with PCA normals.
inline constexpr int kModelFeaturesRevision = 2;

// Row-major float, kFeatureDescriptorSize columns: one row per described keypoint.
inline constexpr int kFeatureDescriptorSize = 32;
using FeatureDescriptors = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Every part of a ModelFeatures as plain data: what a cache stores and gives back.
struct ModelFeatureParts {
  double surface_area = 0.0;
  double voxel = 0.0;
  ModelKeypoints keypoints;
  FeatureDescriptors descriptors;
  std::vector<Eigen::Isometry3d> symmetries;
};

class ModelFeatures {
 public:
  // `model` must outlive this object. Throws std::runtime_error when the model has no surface
  // area to sample (no surfaces, empty trimmed faces).
  explicit ModelFeatures(const engine::PreparedModel& model, FeatureOptions options = {});
  ModelFeatures(const engine::PreparedModel&& model, FeatureOptions options = {}) = delete;

  // The features of `model` and `options` from their stored parts (as the accessors gave them
  // after build_all() for the same model and options): nothing is built, every accessor
  // returns the parts as given.
  // Checked: the model has surfaces, the area is finite and positive and the voxel the one it
  // gives with options.keypoints, one normal per keypoint and one descriptor row of
  // kFeatureDescriptorSize per described keypoint (computed here from the keypoints), every
  // number finite; std::invalid_argument naming the part otherwise. That
  // the parts belong to this model and these options is the caller's to know (the cache's key).
  static std::shared_ptr<const ModelFeatures> from_parts(const engine::PreparedModel& model,
                                                         FeatureOptions options,
                                                         ModelFeatureParts parts);
  static std::shared_ptr<const ModelFeatures> from_parts(const engine::PreparedModel&& model,
                                                         FeatureOptions options,
                                                         ModelFeatureParts parts) = delete;

  // The features of `model` and `options` from their area, voxel and keypoints alone (as the
  // accessors gave them for the same model and options; parts.descriptors and parts.symmetries
  // empty): what an alignment from a given pose needs. The descriptors and symmetries are built
  // on first use, as in a fresh object, and are then the same bits. The same checks as
  // from_parts, std::invalid_argument naming the part.
  static std::shared_ptr<const ModelFeatures> from_samples(const engine::PreparedModel& model,
                                                           FeatureOptions options,
                                                           ModelFeatureParts parts);
  static std::shared_ptr<const ModelFeatures> from_samples(const engine::PreparedModel&& model,
                                                           FeatureOptions options,
                                                           ModelFeatureParts parts) = delete;

  // Builds the keypoints, descriptors and symmetries now if they are not yet (what a cache
  // stores; the global alignment needs all three).
  void build_all() const;

  const FeatureOptions& options() const { return options_; }
  double surface_area() const { return area_; }
  // Sample spacing (model units): sqrt(area / keypoints).
  double voxel() const { return voxel_; }
  // Area-uniform samples, one per voxel, with exact normals: the model's surface for the
  // hypotheses' overlap, the verdict's coverage and the symmetry search.
  const ModelKeypoints& keypoints() const;
  // The keypoints as a scan's keypoints are described: those where PCA over the keypoints
  // (normal_radius) finds a surface, with their PCA normals, in keypoint order. The scan's
  // normals come from PCA; exact ones would differ wherever the surface bends within the
  // radius, and a descriptor compares normals.
  const ModelKeypoints& described_keypoints() const;
  // Row i describes described_keypoints().points[i]; row-major float, 32 columns.
  const FeatureDescriptors& descriptors() const;
  // The model's discrete rotational symmetries (model frame, identity excluded): turns that map
  // the model onto itself, checked by exact distances (model_symmetry.hpp in src). A scan of a
  // symmetric part fits as well in every pose S * T as in T; the coarse report lists them.
  const std::vector<Eigen::Isometry3d>& symmetries() const;

 private:
  struct FromParts {};
  ModelFeatures(FromParts, const engine::PreparedModel& model, FeatureOptions options,
                ModelFeatureParts parts, ModelKeypoints described);
  struct FromSamples {};
  ModelFeatures(FromSamples, const engine::PreparedModel& model, FeatureOptions options,
                ModelFeatureParts parts);

  const engine::PreparedModel& model_;
  FeatureOptions options_;
  double area_ = 0.0;
  double voxel_ = 0.0;
  mutable std::once_flag keypoints_once_, described_once_, descriptors_once_, symmetries_once_;
  mutable ModelKeypoints keypoints_;
  mutable ModelKeypoints described_;
  mutable FeatureDescriptors descriptors_;
  mutable std::vector<Eigen::Isometry3d> symmetries_;
};

}  // namespace nurbsreg::registration
