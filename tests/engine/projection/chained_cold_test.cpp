// Chained cold frames (ProjectionOptions::chain_cold): a large frame without hints lets each
// point's search list the items near its answer, and the next points of the (fine) locality order
// clip only those while the list proves their answers. Checked here: the answers equal the
// separate searches' (and a brute force on a subset) where proofs must fail often (points between
// the two layers of a hairpin, a fold inside one patch, surfaces touching each other), the lists
// really prove most answers there, the answers do not depend on the thread count or the tasks,
// and the fine locality order is the Morton order of the points' cells.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/engine/spatial_order.hpp"
#include "support/hard_surfaces.hpp"
#include "support/random_entities.hpp"
#include "support/surface_reference.hpp"

namespace nurbsreg::engine {
namespace {

// Points uniform in the box `lo`-`hi`: every one of them a cold query in no spatial order.
std::vector<Vec3> points_in(const Vec3& lo, const Vec3& hi, std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Vec3> points(n);
  for (Vec3& p : points)
    p = test::uniform_point(rng, lo, hi);
  return points;
}

ProjectionResults project(const PreparedModel& model, const std::vector<Vec3>& points, bool chained,
                          ProjectionCounters* counters = nullptr, std::size_t grain = 256) {
  ProjectionOptions options;
  options.chain_cold = chained;
  options.grain = grain;
  ProjectionResults results;
  Projector(model).project(PointView::of(points), options, results, {}, counters);
  return results;
}

struct Scene {
  const char* name;
  Model model;
  Vec3 lo, hi;  // where the points are
};

// Two layers 0.3 apart (points on both sides of the middle, where the nearest layer switches),
// the same fold inside one patch, and the sheet, sphere and torus touching each other.
std::vector<Scene> scenes() {
  std::vector<Scene> out;
  out.push_back({"hairpin", test::model_of({test::hairpin(0.3)}), Vec3(-1.0, -0.3, -0.4),
                 Vec3(10.5, 6.3, 0.7)});
  out.push_back({"folded patch", test::model_of({test::folded_patch(0.25)}), Vec3(-2.0, -0.3, -0.3),
                 Vec3(10.5, 4.8, 0.55)});
  Model touching;
  NurbsSurface sheet = test::random_surface(11, 3, 3, 8, 8, true);
  for (Vec3& p : sheet.control_points)
    p = Vec3(p.x() - 3.5, p.y() - 3.5, 0.3 * p.z());
  touching.surfaces.push_back(sheet);
  touching.surfaces.push_back(make_sphere(Vec3(0, 0, 1.5), 1.5));
  touching.surfaces.push_back(make_torus(Vec3(0, 0, 1.5), 2.5, 0.5));
  out.push_back({"sheet, sphere and torus", touching, Vec3(-3.5, -3.5, -0.5), Vec3(3.5, 3.5, 3.2)});
  return out;
}

// The exact closest point does not depend on how it was found: the distances agree to the
// clipping's own accuracy, and where the entity differs the two are ties.
TEST(ChainedColdFrame, SameAnswersAsSeparateSearches) {
  for (const Scene& scene : scenes()) {
    const PreparedModel model(scene.model);
    const std::vector<Vec3> points = points_in(scene.lo, scene.hi, 60000, 3);
    ProjectionCounters counters;
    const ProjectionResults chained = project(model, points, true, &counters);
    const ProjectionResults separate = project(model, points, false);
    const double tolerance = 1e-10 * model.bounds().diagonal();
    for (std::size_t i = 0; i < points.size(); ++i) {
      ASSERT_EQ(chained.status[i], ProjectionStatus::ok) << scene.name << " point " << i;
      ASSERT_NEAR(chained.distance[i], separate.distance[i], tolerance)
          << scene.name << " point " << i << " " << points[i].transpose();
      ASSERT_NEAR((points[i] - chained.foot[i]).norm(), chained.distance[i], tolerance);
    }
    // The lists must have proved most answers (else this test would check the walk only), and
    // failed at many (points by the middle of the hairpin, the fold and the contacts).
    EXPECT_GT(counters.listed, points.size() / 2) << scene.name;
    EXPECT_GT(counters.lists_made, points.size() / 50) << scene.name;
  }
}

// An independent brute force (dense samples polished by Newton) on the hairpin's points: the
// chained answers are never farther, and they are surface points at the reported parameters.
TEST(ChainedColdFrame, NoFartherThanABruteForceBetweenTwoLayers) {
  const NurbsSurface surface = test::hairpin(0.3);
  const PreparedModel model(test::model_of({surface}));
  const std::vector<Vec3> points =
      points_in(Vec3(-1.0, -0.3, -0.4), Vec3(10.5, 6.3, 0.7), 30000, 9);
  ProjectionCounters counters;
  const ProjectionResults chained = project(model, points, true, &counters);
  ASSERT_GT(counters.listed, points.size() / 2);
  const test::SurfaceReference reference(surface, 300, 3000, 300);
  const double tolerance = 1e-9 * model.bounds().diagonal();
  for (std::size_t i = 0; i < points.size(); i += 97) {
    const test::ReferenceHit ref = reference.closest(points[i]);
    EXPECT_LE(chained.distance[i], std::sqrt(ref.distance_sq) + tolerance)
        << "point " << i << " " << points[i].transpose();
    EXPECT_LT((surface.evaluate(chained.u[i], chained.v[i]) - chained.foot[i]).norm(), tolerance);
  }
}

// Chains start at fixed places of the order, so one thread, two threads and any task size give
// the same bits.
TEST(ChainedColdFrame, SameBitsForAnyThreadCountAndTaskSize) {
  const Scene scene = scenes()[0];
  const PreparedModel model(scene.model);
  const std::vector<Vec3> points = points_in(scene.lo, scene.hi, 40000, 5);
  ProjectionResults one, two;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = project(model, points, true);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    two = project(model, points, true, nullptr, 7);
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_EQ(one.distance[i], two.distance[i]) << "point " << i;
    ASSERT_EQ(one.u[i], two.u[i]) << "point " << i;
    ASSERT_EQ(one.v[i], two.v[i]) << "point " << i;
    ASSERT_EQ(one.foot[i], two.foot[i]) << "point " << i;
  }
}

// A Morton key written here independently: bit k of cell x goes to bit 3k, of y to 3k + 1, of z
// to 3k + 2, over 2^bits cubic cells along the box's longest side.
std::uint64_t morton_key(const Vec3& p, const Vec3& lo, double cells_per_unit, int bits) {
  std::uint64_t key = 0;
  for (int a = 0; a < 3; ++a) {
    const auto c = static_cast<std::uint64_t>(
        std::min((p[a] - lo[a]) * cells_per_unit, static_cast<double>((1 << bits) - 1)));
    for (int k = 0; k < bits; ++k)
      key |= ((c >> k) & 1u) << (3 * k + a);
  }
  return key;
}

TEST(SpatialOrder, FineGridIsTheStableMortonOrderOfTheCells) {
  const std::vector<Vec3> points = points_in(Vec3(-2, 0, 1), Vec3(5, 1, 1.5), 50000, 11);
  FrameVector<std::uint32_t> order;
  SpatialOrderScratch scratch;
  spatial_order(PointView::of(points), order, scratch, kMaxOrderBits);
  Vec3 lo = points[0], hi = points[0];
  for (const Vec3& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double cells_per_unit = (1 << kMaxOrderBits) / (hi - lo).maxCoeff();
  // Stable: by key, then by index.
  std::vector<std::pair<std::uint64_t, std::uint32_t>> expected(points.size());
  for (std::uint32_t i = 0; i < points.size(); ++i)
    expected[i] = {morton_key(points[i], lo, cells_per_unit, kMaxOrderBits), i};
  std::sort(expected.begin(), expected.end());
  ASSERT_EQ(order.size(), expected.size());
  for (std::size_t k = 0; k < expected.size(); ++k)
    ASSERT_EQ(order[k], expected[k].second) << "position " << k;
}

}  // namespace
}  // namespace nurbsreg::engine
