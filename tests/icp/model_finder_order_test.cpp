// ModelCorrespondenceFinder answers large queries in spatial order (its per-point state stored
// in engine::spatial_order, the answers put back in query order). Only the storage moves, so a
// finder in spatial order must give the same bits as one in query order: every correspondence,
// last_results(), the counters (the same hints and borrowed certificates do the same work), the
// points that stopped borrowing, and through all of them the ICP pose. Checked on a scan in
// random order (a synthetic scan's order), large enough to be ordered, through the query
// sequence of a coarse-to-fine alignment and through IcpSolver itself.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <random>
#include <vector>

#include "nurbsreg/engine/cancellation.hpp"
#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::icp {
namespace {

using engine::Vec3;

bool same_bits(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

void expect_same_results(const engine::ProjectionResults& a, const engine::ProjectionResults& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(a.status[k], b.status[k]) << k;
    ASSERT_EQ(a.entity[k], b.entity[k]) << k;
    ASSERT_TRUE(same_bits(a.u[k], b.u[k]) && same_bits(a.v[k], b.v[k])) << k;
    ASSERT_TRUE(same_bits(a.distance[k], b.distance[k])) << k;
    ASSERT_TRUE(same_bits(a.signed_distance[k], b.signed_distance[k])) << k;
    ASSERT_EQ(a.on_trim_edge[k], b.on_trim_edge[k]) << k;
    if (!a.certificate.empty() && !b.certificate.empty()) {
      ASSERT_EQ(a.certificate[k].anchor, b.certificate[k].anchor) << k;
      ASSERT_EQ(a.certificate[k].radius, b.certificate[k].radius) << k;
    }
  }
}

void expect_same_answers(const std::vector<Correspondence>& a,
                         const std::vector<Correspondence>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(a[k].valid, b[k].valid) << k;
    if (!a[k].valid) continue;
    ASSERT_TRUE(same_bits(a[k].distance, b[k].distance)) << k;
    ASSERT_EQ(a[k].foot, b[k].foot) << k;
    ASSERT_EQ(a[k].normal, b[k].normal) << k;
    ASSERT_EQ(a[k].on_boundary, b[k].on_boundary) << k;
  }
}

void expect_same_counters(const engine::ProjectionCounters& a,
                          const engine::ProjectionCounters& b) {
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.patches_visited, b.patches_visited);
  EXPECT_EQ(a.newton_iterations, b.newton_iterations);
  EXPECT_EQ(a.subdivisions, b.subdivisions);
  EXPECT_EQ(a.certified, b.certified);
  EXPECT_EQ(a.certificates_made, b.certificates_made);
}

class ModelFinderOrder : public ::testing::Test {
 protected:
  // A wavy sheet of 7 x 7 bicubic patches with an open edge, and a scan of it in random order:
  // points near the sheet, some beyond its edge, some far above it.
  ModelFinderOrder() : prepared_(model()), ordered_(prepared_), plain_(prepared_) {
    ordered_.use_spatial_order(true);
    plain_.use_spatial_order(false);
    std::mt19937_64 rng(31);
    const engine::NurbsSurface& s = prepared_.model().surfaces.front();
    const double du = s.domain_u().width(), dv = s.domain_v().width();
    for (std::size_t i = 0; i < kPoints; ++i) {
      const double u = test::uniform(rng, s.domain_u().lo - 0.05 * du, s.domain_u().hi);
      const double v = test::uniform(rng, s.domain_v().lo, s.domain_v().hi + 0.05 * dv);
      const double h = i % 20 == 0 ? test::uniform(rng, 1.0, 5.0) : test::uniform(rng, -0.2, 0.2);
      const double cu = std::clamp(u, s.domain_u().lo, s.domain_u().hi);
      const double cv = std::clamp(v, s.domain_v().lo, s.domain_v().hi);
      scan_.push_back(s.evaluate(cu, cv) + Vec3(cu - u, v - cv, h));
    }
  }
  static engine::Model model() {
    engine::Model m;
    m.surfaces.push_back(test::random_surface(41, 3, 3, 10, 10, false));
    return m;
  }

  // The scan points `ids` (all when empty) moved by `shift`, to both finders; their answers and
  // states must agree bit for bit.
  void reset_both() {
    ordered_.reset(scan_.size());
    plain_.reset(scan_.size());
  }

  void find_both(const std::vector<std::size_t>& ids, double shift, double expected_motion) {
    ModelCorrespondenceFinder& ordered = ordered_;
    ModelCorrespondenceFinder& plain = plain_;
    std::vector<Vec3> points;
    const Vec3 offset(shift, -0.5 * shift, 0.3 * shift);
    if (ids.empty()) {
      for (const Vec3& p : scan_)
        points.push_back(p + offset);
    } else {
      for (const std::size_t i : ids)
        points.push_back(scan_[i] + offset);
    }
    CorrespondenceQuery query;
    query.points = points;
    query.scan_indices = ids;
    query.expected_motion = expected_motion;
    std::vector<Correspondence> a(points.size()), b(points.size());
    ordered.find(query, a);
    plain.find(query, b);
    expect_same_answers(a, b);
    expect_same_results(ordered.last_results(), plain.last_results());
    expect_same_counters(ordered.last_counters(), plain.last_counters());
    for (std::size_t s = 0; s < scan_.size(); ++s)
      ASSERT_EQ(ordered.stopped_borrowing(s), plain.stopped_borrowing(s)) << s;
  }

  std::vector<std::size_t> random_subset(std::size_t count, std::uint64_t seed) const {
    std::vector<std::size_t> ids(scan_.size());
    for (std::size_t i = 0; i < ids.size(); ++i)
      ids[i] = i;
    std::mt19937_64 rng(seed);
    std::shuffle(ids.begin(), ids.end(), rng);
    ids.resize(count);
    return ids;
  }

  static constexpr std::size_t kPoints = 3 * ModelCorrespondenceFinder::kSpatialOrderMin;
  engine::PreparedModel prepared_;
  // The same queries to both: one in spatial order, one in query order.
  ModelCorrespondenceFinder ordered_, plain_;
  std::vector<Vec3> scan_;
};

// The queries of a coarse-to-fine alignment, and the odd ones: a subsample large enough to be
// ordered (certifying: its certificates join the atlas), the same again (hints in place), a
// superset (hints carried by scan index, certificates borrowed), every point twice, a small
// query in between (not ordered) and every point after it, a query naming points twice.
TEST_F(ModelFinderOrder, AnswersInSpatialOrderAreTheSameBits) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  reset_both();
  const std::vector<std::size_t> coarse = random_subset(kPoints / 2, 7);
  const std::vector<std::size_t> small = random_subset(1000, 8);
  find_both(coarse, 0.0, 0.001);
  find_both(coarse, 0.001, 0.001);
  find_both({}, 0.002, 0.001);
  find_both({}, 0.0021, 0.0001);
  find_both(small, 0.0022, 0.0001);
  find_both({}, 0.0023, 0.0001);
  std::vector<std::size_t> twice = coarse;
  twice.insert(twice.end(), coarse.begin(), coarse.begin() + 5000);
  find_both(twice, 0.0024, 0.0001);
  // The check compares something: the large queries borrowed certificates and some points
  // stopped borrowing.
  std::size_t stopped = 0;
  for (std::size_t s = 0; s < scan_.size(); ++s)
    stopped += ordered_.stopped_borrowing(s);
  EXPECT_GT(stopped, 0u);
}

// A query cut short (cancelled, as Python's Ctrl-C does it) throws and leaves the finder able to
// answer the next query without a reset(): afresh, exactly, and the same bits in both orders.
TEST_F(ModelFinderOrder, AQueryCutShortLeavesTheNextOneExact) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  reset_both();
  const std::vector<std::size_t> coarse = random_subset(kPoints / 2, 9);
  find_both(coarse, 0.0, 0.001);
  for (ModelCorrespondenceFinder* finder : {&ordered_, &plain_}) {
    CorrespondenceQuery query;
    query.points = scan_;
    std::vector<Correspondence> out(scan_.size());
    tbb::task_group_context context;
    tbb::task_group group(context);
    bool threw = false;
    group.run_and_wait([&] {
      context.cancel_group_execution();
      try {
        finder->find(query, out);
      } catch (const engine::Cancelled&) {
        threw = true;
      }
    });
    EXPECT_TRUE(threw);
  }
  find_both({}, 0.001, 0.001);
  find_both({}, 0.0011, 0.0001);
  engine::Projector reference(prepared_);
  engine::ProjectionResults cold;
  const engine::ProjectionResults& warm = ordered_.last_results();
  std::vector<Vec3> moved;
  for (const Vec3& p : scan_)
    moved.push_back(p + Vec3(0.0011, -0.00055, 0.00033));
  reference.project(engine::PointView::of(moved), {}, cold);
  for (std::size_t k = 0; k < scan_.size(); ++k)
    ASSERT_NEAR(warm.distance[k], cold.distance[k], 1e-9 * prepared_.bounds().diagonal()) << k;
}

// Through the solver: a coarse-to-fine point-to-plane alignment of the scan from a small offset
// ends at the same pose, bit for bit, after the same iterations (a few per stage: the sheet lets
// the scan slide, and more would only repeat the same passes).
TEST_F(ModelFinderOrder, IcpGivesTheSamePose) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  IcpOptions options;
  options.coarse_sizes = {2000, ModelCorrespondenceFinder::kSpatialOrderMin + 2000};
  options.max_iterations = 5;
  const Eigen::Isometry3d init =
      engine::pose_from_euler_degrees(0.5, -0.3, 0.4, Vec3(0.02, -0.01, 0.03));
  const IcpResult a = IcpSolver(options).align(ordered_, scan_, init);
  const IcpResult b = IcpSolver(options).align(plain_, scan_, init);
  EXPECT_EQ(a.T_model_scan.matrix(), b.T_model_scan.matrix());
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_TRUE(same_bits(a.rms, b.rms));
  EXPECT_GE(a.iterations, 3);
  expect_same_results(ordered_.last_results(), plain_.last_results());
}

// By default only models of many patches are answered in spatial order (where it pays).
TEST_F(ModelFinderOrder, LargeModelsAreOrderedByDefault) {
  EXPECT_LT(prepared_.patch_count(), ModelCorrespondenceFinder::kSpatialOrderMinPatches);
  EXPECT_FALSE(ModelCorrespondenceFinder(prepared_).uses_spatial_order());
  engine::Model large;
  for (std::uint64_t seed = 43; seed < 48; ++seed)
    large.surfaces.push_back(test::random_surface(seed, 3, 3, 26, 26, false));
  const engine::PreparedModel prepared(large);
  EXPECT_GE(prepared.patch_count(), ModelCorrespondenceFinder::kSpatialOrderMinPatches);
  EXPECT_TRUE(ModelCorrespondenceFinder(prepared).uses_spatial_order());
}

}  // namespace
}  // namespace nurbsreg::icp
