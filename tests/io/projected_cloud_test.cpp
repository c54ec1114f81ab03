// io::project_cloud: the rows of a cloud do not depend on its block size, in particular not on
// whether the blocks follow the cloud's spatial order (clouds larger than one block) or its
// index order; every point's row is the one Projector::project gives it on its own.
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
  engine::ProjectionResults reference;
  engine::ProjectionOptions plain;
  plain.locality_order = false;
  projector.project(engine::PointView::of(cloud.points), plain, reference);
  // One block (index order), and blocks of the spatial order that do not divide the cloud.
  for (const std::size_t block : {cloud.size(), std::size_t{1777}}) {
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
    const std::size_t blocks = (cloud.size() + block - 1) / block;
    ASSERT_EQ(done.size(), blocks);
    EXPECT_EQ(done.front(), std::min(block, cloud.size()));
    EXPECT_EQ(done.back(), cloud.size());
  }
}

}  // namespace
}  // namespace nurbsreg::io
