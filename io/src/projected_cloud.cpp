#include "nurbsreg/io/projected_cloud.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <span>
#include <vector>

#include "nurbsreg/engine/spatial_order.hpp"

namespace nurbsreg::io {

ProjectedCloud project_cloud(engine::Projector& projector, const PointCloud& cloud,
                             engine::ProjectionTarget target, const ProjectProgress& progress,
                             std::size_t block_size) {
  ProjectedCloud out;
  out.target = target;
  engine::ProjectionOptions options;
  options.target = target;
  // A large cloud of surface queries is one chained cold frame (engine::ProjectionOptions::
  // chain_cold) in the fine spatial order of the whole cloud, its margin from that order, cut
  // into blocks of whole chains: the rows do not depend on the block size.
  constexpr std::size_t kChainedCloudMin = 8192;
  const bool chained = target == engine::ProjectionTarget::surfaces &&
                       cloud.size() >= kChainedCloudMin &&
                       cloud.size() <= std::numeric_limits<std::uint32_t>::max();
  block_size = std::max<std::size_t>(1, block_size);
  if (chained) {
    block_size =
        (block_size + engine::kChainLength - 1) / engine::kChainLength * engine::kChainLength;
  }
  // No certificates: the blocks are projected without hints and without certifying.
  out.results.resize(cloud.size(), /*feet=*/true, /*certificates=*/false);
  engine::ProjectionResults block;
  const auto start = std::chrono::steady_clock::now();
  const auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  // Blocks of the cloud's spatial order, not of its index order: a block of a cloud in no spatial
  // order (a synthetic or merged scan) would otherwise spread over the whole model, and each
  // block would walk every part of the hierarchy and every patch again.
  const std::span<const engine::Vec3> all(cloud.points);
  engine::FrameVector<std::uint32_t> order;
  engine::SpatialOrderScratch order_scratch;
  const bool ordered = chained || (cloud.size() > block_size &&
                                   cloud.size() <= std::numeric_limits<std::uint32_t>::max());
  if (chained) {
    engine::spatial_order(engine::PointView::of(all), order, order_scratch, engine::kMaxOrderBits);
    options.chain_margin = engine::chain_margin_for(engine::PointView::of(all), order);
    options.chain_in_index_order = true;
  } else if (ordered) {
    engine::spatial_order(engine::PointView::of(all), order, order_scratch);
  }
  std::vector<engine::Vec3> block_points;
  for (std::size_t begin = 0; begin < cloud.size(); begin += block_size) {
    const std::size_t end = std::min(cloud.size(), begin + block_size);
    if (ordered) {
      const std::span<const std::uint32_t> ids(order.data() + begin, end - begin);
      block_points.resize(ids.size());
      for (std::size_t k = 0; k < ids.size(); ++k)
        block_points[k] = cloud.points[ids[k]];
      projector.project(engine::PointView::of(block_points), options, block);
      out.results.scatter_from(block, ids);
    } else {
      projector.project(engine::PointView::of(all.subspan(begin, end - begin)), options, block);
      out.results.copy_from(block, begin);
    }
    if (progress) progress(end, cloud.size(), seconds());
  }
  out.compute_seconds = seconds();

  const engine::ProjectionResults& r = out.results;
  out.normal_x.resize(cloud.size());
  out.normal_y.resize(cloud.size());
  out.normal_z.resize(cloud.size());
  double min_d = std::numeric_limits<double>::infinity();
  double max_d = 0.0;
  double sum_d = 0.0;
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    out.normal_x[i] = r.normal[i].x();
    out.normal_y[i] = r.normal[i].y();
    out.normal_z[i] = r.normal[i].z();
    min_d = std::min(min_d, r.distance[i]);
    max_d = std::max(max_d, r.distance[i]);
    sum_d += r.distance[i];
    sum_sq += r.distance[i] * r.distance[i];
  }
  const double n = static_cast<double>(cloud.size());
  out.min_distance = cloud.size() ? min_d : 0.0;
  out.max_distance = max_d;
  out.mean_distance = cloud.size() ? sum_d / n : 0.0;
  out.rms_distance = cloud.size() ? std::sqrt(sum_sq / n) : 0.0;
  return out;
}

ProjectionColumns ProjectedCloud::columns(const PointCloud& cloud) const {
  ProjectionColumns c;
  c.index = cloud.source_index;
  c.point = cloud.points;
  c.foot = results.foot;
  c.distance = results.distance;
  c.entity = results.entity;
  c.u = results.u;
  c.v = results.v;
  if (target == engine::ProjectionTarget::surfaces) {
    c.extra = {{"signed_distance", results.signed_distance},
               {"normal_x", normal_x},
               {"normal_y", normal_y},
               {"normal_z", normal_z}};
  }
  return c;
}

}  // namespace nurbsreg::io
