#include "nurbsreg/registration/model_features.hpp"

#include <tbb/task_group.h>

#include <spdlog/spdlog.h>

#include <spdlog/spdlog.h>
#include <chrono>

#include <chrono>
#include <cmath>
#include <stdexcept>

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

}  // namespace

ModelFeatures::ModelFeatures(const engine::PreparedModel& model, FeatureOptions options)
    : model_(model), options_(options) {
  if (model.model().surfaces.empty()) {
    throw std::runtime_error("the model has no surfaces to align a scan to");
  }
  area_ = engine::surface_area(model.model());
  if (!(area_ > 0.0) || !std::isfinite(area_)) {
    throw std::runtime_error("the model's surfaces have no area to align a scan to");
  }
  voxel_ = std::sqrt(area_ / static_cast<double>(std::max<std::size_t>(options_.keypoints, 16)));
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

const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>&
ModelFeatures::descriptors() const {
  std::call_once(descriptors_once_, [&] {
    build_isolated([&] {
      const ModelKeypoints& k = keypoints();
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
