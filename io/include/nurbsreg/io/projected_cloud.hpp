#pragma once
// A whole cloud projected onto a prepared model and laid out as the contract's projection table
// (CONTRACT.md §2 "Projection results"): what `project`, `batch --mode project` and the service's
// POST /v1/project compute, by one function, so that a cloud gives the same rows everywhere.
//
// project_cloud projects in blocks of kProjectBlock points (progress between blocks) without
// hints or certificates, so the rows depend on neither the block size nor the thread count. A
// cloud of 8,192 surface queries or more is one chained cold frame (engine::ProjectionOptions::
// chain_cold) in the fine spatial order of the whole cloud (engine::spatial_order), cut into
// blocks of whole chains (the block size is rounded up to a multiple of engine::kChainLength);
// a smaller cloud of more than one block is taken in its spatial order too. Each block is a
// compact part of the cloud, and every row is put back at its point's index. The rows are exact
// closest points; in a chained cloud their last bits may depend on the cloud's other points (a
// near list's clipping starts where its previous point's answer was), never on the blocks.
// Surfaces add the columns signed_distance, normal_x, normal_y, normal_z. Thread safety: one
// call at a time per Projector; allocates the results (not per point).

#include <cstddef>
#include <functional>
#include <vector>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/projection_results.hpp"

namespace nurbsreg::io {

inline constexpr std::size_t kProjectBlock = std::size_t{1} << 18;

struct ProjectedCloud {
  engine::ProjectionTarget target = engine::ProjectionTarget::surfaces;
  engine::ProjectionResults results;  // with feet and normals, in cloud order
  std::vector<double> normal_x, normal_y, normal_z;
  double compute_seconds = 0.0;  // projection only
  // Distance statistics over the cloud's points (0 for an empty cloud).
  double min_distance = 0.0;
  double mean_distance = 0.0;
  double rms_distance = 0.0;
  double max_distance = 0.0;

  // Views for the table writers; `cloud` must be the projected one and outlive the views.
  ProjectionColumns columns(const PointCloud& cloud) const;
};

// Called after each block with the points done so far and the seconds spent. It may throw to
// stop the work (a service's time limit): the exception propagates, nothing is returned.
using ProjectProgress = std::function<void(std::size_t done, std::size_t total, double seconds)>;

// `block`: points per block (> 0; the rows do not depend on it; rounded up to a multiple of
// engine::kChainLength for a chained cloud), i.e. how often `progress` is called.
ProjectedCloud project_cloud(engine::Projector& projector, const PointCloud& cloud,
                             engine::ProjectionTarget target, const ProjectProgress& progress = {},
                             std::size_t block = kProjectBlock);

}  // namespace nurbsreg::io
