// io::project_cloud: the rows of a cloud do not depend on its block size (a chained cold frame in
// the whole cloud's fine spatial order, cut into blocks of whole chains), and every row is the
// exact closest point a separate search finds for its point alone.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include <tbb/global_control.h>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/io/projected_cloud.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::io {
namespace {

using engine::Vec3;

// Two sheets far apart, so that a cloud in random order sends consecutive points to different
// patches, and consecutive blocks of the spatial order cover different parts of the model.
engine::Model two_sheets() {
  engine::Model m;
  for (int k = 0; k < 2; ++k) {
    engine::NurbsSurface s = test::random_surface(40 + k, 3, 3, 10, 10, k == 1);
    for (Vec3& p : s.control_points)
      p += Vec3(20.0 * k, 0.0, 0.0);
    m.surfaces.push_back(std::move(s));
  }
  return m;
}

PointCloud random_cloud(const engine::Aabb& box, std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  PointCloud cloud;
  const Vec3 margin = 0.1 * (box.hi - box.lo);
  for (std::size_t i = 0; i < n; ++i) {
    cloud.points.push_back(test::uniform_point(rng, box.lo - margin, box.hi + margin));
    cloud.source_index.push_back(i);
  }
  cloud.total = n;
  cloud.width = static_cast<std::uint32_t>(n);
  cloud.height = 1;
  return cloud;
}

TEST(ProjectedCloud, RowsDoNotDependOnTheBlocks) {
  const engine::PreparedModel prepared(two_sheets());
  const PointCloud cloud = random_cloud(prepared.bounds(), 20000, 3);
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  engine::Projector projector(prepared);
  // A separate search per point, in index order: the same closest points.
  engine::ProjectionResults separate;
  engine::ProjectionOptions plain;
  plain.locality_order = false;
  plain.chain_cold = false;
  projector.project(engine::PointView::of(cloud.points), plain, separate);
  const ProjectedCloud whole =
      project_cloud(projector, cloud, engine::ProjectionTarget::surfaces, {}, cloud.size());
  const double tolerance = 1e-10 * prepared.bounds().diagonal();
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    ASSERT_EQ(whole.results.status[i], separate.status[i]) << i;
    ASSERT_NEAR(whole.results.distance[i], separate.distance[i], tolerance) << i;
  }
  const engine::ProjectionResults& reference = whole.results;
  // Blocks of whole chains (1777 is rounded up to 1792), one of them of the chain length itself.
  for (const std::size_t block : {std::size_t{1777}, engine::kChainLength}) {
    std::vector<std::size_t> done;
    const ProjectedCloud projected = project_cloud(
        projector, cloud, engine::ProjectionTarget::surfaces,
        [&done](std::size_t d, std::size_t total, double) {
          EXPECT_EQ(total, 20000u);
          done.push_back(d);
        },
        block);
    const engine::ProjectionResults& r = projected.results;
    ASSERT_EQ(r.size(), cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      ASSERT_EQ(r.status[i], reference.status[i]) << "block " << block << ", point " << i;
      ASSERT_EQ(r.distance[i], reference.distance[i]) << "block " << block << ", point " << i;
      ASSERT_EQ(r.signed_distance[i], reference.signed_distance[i]) << i;
      ASSERT_EQ(r.entity[i], reference.entity[i]) << i;
      ASSERT_EQ(r.u[i], reference.u[i]) << i;
      ASSERT_EQ(r.v[i], reference.v[i]) << i;
      ASSERT_EQ(r.foot[i], reference.foot[i]) << i;
      ASSERT_EQ(r.normal[i], reference.normal[i]) << i;
      ASSERT_EQ(r.on_trim_edge[i], reference.on_trim_edge[i]) << i;
      ASSERT_EQ(projected.normal_x[i], reference.normal[i].x()) << i;
    }
    // Progress after every block, up to the whole cloud.
    const std::size_t rounded =
        (block + engine::kChainLength - 1) / engine::kChainLength * engine::kChainLength;
    const std::size_t blocks = (cloud.size() + rounded - 1) / rounded;
    ASSERT_EQ(done.size(), blocks);
    EXPECT_EQ(done.front(), std::min(rounded, cloud.size()));
    EXPECT_EQ(done.back(), cloud.size());
  }
}

}  // namespace
}  // namespace nurbsreg::io
