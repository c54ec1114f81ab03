#pragma once
// Synthetic scans of a model for demos, tests and benchmarks (`nurbsreg synth`): area-uniform
// points, Gaussian noise along the normal, a rigid pose, optional outliers and a partial view.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::engine {

struct SyntheticScanOptions {
  std::size_t points = 10000;
  // Standard deviation of Gaussian noise added along the surface normal (model units).
  double noise_sigma = 0.0;
  // Fraction of the points replaced by outliers drawn uniformly in the scan's box: the box of
  // the visible samples (a partial view's own box, not the model's), as clutter in front of a
  // scanner fills the space around what it sees.
  double outlier_fraction = 0.0;
  // Fraction of the points replaced by a fixture under the part: a plane perpendicular to
  // `fixture_up` touching the visible samples' lowest point along it, spanning their extent
  // across it plus half of it on every side (a table wider than the part), with the same noise
  // along its normal. Clustered clutter that a uniform cloud does not test: a large flat patch
  // that point-to-plane ICP and plane-like features can lock onto.
  double fixture_fraction = 0.0;
  Vec3 fixture_up = Vec3::UnitZ();
  // Partial view: keep only the part of the model seen from `view_direction`, i.e. the
  // `view_fraction` of the samples with the largest projection on that direction (1 = all).
  double view_fraction = 1.0;
  Vec3 view_direction = Vec3::UnitZ();
  // Pose of the scanner: scan_point = T_scan_model * model_point.
  Eigen::Isometry3d T_scan_model = Eigen::Isometry3d::Identity();
  std::uint64_t seed = 1;

  std::optional<std::string> validate() const;
};

struct SyntheticScan {
  std::vector<Vec3> points;  // in the scan frame
  // For each point: true when it was drawn on the model (not an outlier or the fixture), with
  // its exact source sample (surface, u, v) before noise.
  std::vector<bool> on_model;
  std::vector<int> surface;
  std::vector<Vec2> uv;
  // The pose alignment must recover: model_point = T_model_scan * scan_point.
  Eigen::Isometry3d T_model_scan = Eigen::Isometry3d::Identity();
};

// Requires a model with at least one surface.
SyntheticScan make_synthetic_scan(const Model& model, const SyntheticScanOptions& options);

// "rx ry rz tx ty tz": rotations in degrees about the fixed x, then y, then z axes, then a
// translation in model units (the `--pose` argument of `nurbsreg synth`).
Eigen::Isometry3d pose_from_euler_degrees(double rx, double ry, double rz, const Vec3& t);

}  // namespace nurbsreg::engine
