// Cancellation from outside, as Python's Ctrl-C does it (the call's TBB task group cancelled
// from another thread): wherever it lands in an alignment from any pose, the call either ends
// (engine::Cancelled, or the group reports itself cancelled) or completes, never goes on with
// a cancelled loop's partial results (which crashed in the feature matching), and the same
// Aligner's next call gives a fresh aligner's bits.
#include <gtest/gtest.h>
#include <tbb/task_group.h>

#include <chrono>
#include <random>
#include <thread>

#include "global_support.hpp"
#include "nurbsreg/engine/cancellation.hpp"
#include "support/test_scale.hpp"

namespace nurbsreg::registration {
namespace {

engine::SyntheticScan panel_scan(std::size_t points, std::uint64_t seed) {
  const testing::Part& p = testing::part(testing::kPanel);
  std::mt19937_64 rng(seed);
  engine::SyntheticScanOptions o;
  o.points = points;
  o.noise_sigma = 1e-4 * p.size;
  o.outlier_fraction = 0.1;
  o.T_scan_model = testing::random_pose(rng, p.size);
  o.seed = seed;
  return engine::make_synthetic_scan(p.model->model(), o);
}

TEST(Cancellation, AnAlignmentCancelledAnywhereEndsAndTheAlignerStillWorks) {
  const testing::Part& p = testing::part(testing::kPanel);
  const engine::SyntheticScan big = panel_scan(nurbsreg::test::test_size(40000, 10000), 3);
  const engine::SyntheticScan small = panel_scan(3000, 4);
  Aligner fresh(*p.model, icp::IcpOptions{}, {}, p.features);
  const AlignmentResult expected = fresh.align(small.points);
  ASSERT_TRUE(expected.ok());

  // The uncancelled call's time: the cancellations below land at fractions of it.
  const auto start = std::chrono::steady_clock::now();
  ASSERT_TRUE(fresh.align(big.points).ok());
  const auto full = std::chrono::steady_clock::now() - start;

  int ended = 0;
  for (const double fraction : {0.0, 0.02, 0.1, 0.3, 0.6, 0.9}) {
    SCOPED_TRACE(::testing::Message() << "cancelled at " << fraction << " of the call");
    Aligner aligner(*p.model, icp::IcpOptions{}, {}, p.features);
    tbb::task_group_context context;
    std::thread canceller([&] {
      std::this_thread::sleep_for(
          std::chrono::duration_cast<std::chrono::microseconds>(full * fraction));
      context.cancel_group_execution();
    });
    bool threw = false;
    tbb::task_group group(context);
    tbb::task_group_status status = tbb::task_group_status::not_complete;
    try {
      status = group.run_and_wait([&] { aligner.align(big.points); });
    } catch (const engine::Cancelled&) {
      threw = true;
    }
    canceller.join();
    if (threw || status == tbb::task_group_status::canceled) ++ended;
    const AlignmentResult again = aligner.align(small.points);
    ASSERT_TRUE(again.ok()) << again.failure.value_or("");
    EXPECT_TRUE(again.icp.T_model_scan.matrix() == expected.icp.T_model_scan.matrix());
    EXPECT_EQ(again.fit.inlier_fraction, expected.fit.inlier_fraction);
  }
  // At least the early cancellations must have stopped the call (else this test shows nothing).
  EXPECT_GE(ended, 3);
}

}  // namespace
}  // namespace nurbsreg::registration
