// registration::Aligner from any pose (issue 25): seeded random rotations over all of SO(3) and
// translations of a few model sizes, on the example panel, the IEA blade and two trimmed real
// parts (bearing, linkrods), with noise, 30% outliers (uniform, and a clutter plane) and half
// views: every trial ends at noise level, or fails loudly, never with a wrong pose reported good.
// Plus the 180-degree NIST case of the issue and determinism over thread counts. Kept fast: small
// scans, a few trials per part spread over the conditions, each model's features built once;
// the large sweeps are bench/align_global.
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <vector>

#include "global_support.hpp"
#include "support/test_scale.hpp"

namespace nurbsreg::registration {
namespace {

using Eigen::Isometry3d;
using engine::Vec3;
using testing::Errors;
using testing::part;
using testing::pose_error;
using testing::random_pose;

// A scan of `points` points of the part at a random pose (seed 9), noise 1e-4 of its size, 20%
// uniform outliers.
engine::SyntheticScan scan_with_outliers(const testing::Part& p, std::size_t points) {
  engine::SyntheticScanOptions o;
  o.points = points;
  o.noise_sigma = 1e-4 * p.size;
  o.outlier_fraction = 0.2;
  std::mt19937_64 rng(9);
  o.T_scan_model = random_pose(rng, p.size);
  return engine::make_synthetic_scan(p.model->model(), o);
}

struct Condition {
  const char* name;
  double outliers;
  double view;
};
constexpr Condition kFull{"full", 0.0, 1.0};
constexpr Condition kOutliers{"outliers 30%", 0.3, 1.0};
constexpr Condition kHalf{"half view", 0.0, 0.5};

// One trial per condition in `conditions`, each at its own random pose: a good fit within
// noise-level error, or (allow_failure) a loud failure, never a good fit at a wrong pose.
void run_trials(const std::string& path, std::size_t points, std::vector<Condition> conditions,
                std::uint64_t seed, bool allow_failure = false) {
  const testing::Part& p = part(path);
  const double noise = 1e-4 * p.size;
  Aligner aligner(*p.model, icp::IcpOptions{}, {}, p.features);
  std::mt19937_64 rng(seed);
  int t = 0;
  for (const Condition& c : conditions) {
    engine::SyntheticScanOptions o;
    o.points = points;
    o.noise_sigma = noise;
    o.outlier_fraction = c.outliers;
    o.view_fraction = c.view;
    o.view_direction = Vec3(0.3, -0.5, 1.0).normalized();
    o.T_scan_model = random_pose(rng, p.size);
    o.seed = seed + static_cast<std::uint64_t>(t++);
    const engine::SyntheticScan scan = engine::make_synthetic_scan(p.model->model(), o);
    const AlignmentResult r = aligner.align(scan.points);
    const Errors e = pose_error(scan.T_model_scan, r.icp.T_model_scan);
    SCOPED_TRACE(::testing::Message() << c.name << " trial " << t << ": rotation error "
                                      << e.degrees << " deg, translation error " << e.translation
                                      << ", failure " << r.failure.value_or("none"));
    ASSERT_TRUE(r.coarse.has_value());
    if (allow_failure && !r.ok()) continue;
    ASSERT_TRUE(r.ok());
    EXPECT_TRUE(r.fit.good);
    EXPECT_LT(e.degrees, 0.05);
    EXPECT_LT(e.translation, 5e-4 * p.size);
  }
}

TEST(GlobalAlignment, PanelFromAnyPose) {
  // Under sanitizers (test_scale.hpp) each condition once.
  std::vector<Condition> conditions = {kFull, kOutliers, kHalf};
  if (!nurbsreg::test::kReducedTests)
    conditions.insert(conditions.end(), {kFull, kOutliers, kHalf});
  run_trials(testing::kPanel, 5000, conditions, 11);
}

TEST(GlobalAlignment, IeaBladeFromAnyPose) {
  run_trials(testing::kReal + "iea-15mw/IEA_15MW_CFD.stp", 6000, {kFull, kOutliers, kHalf}, 21);
}

TEST(GlobalAlignment, BearingFromAnyPose) {
  run_trials(testing::kReal + "occt/bearing.iges", 6000, {kFull, kOutliers, kHalf}, 31);
}

TEST(GlobalAlignment, LinkrodsFromAnyPose) {
  run_trials(testing::kReal + "occt/linkrods.step", 6000, {kFull, kOutliers, kHalf}, 41);
}

// The case of issue 25: ICP from the identity ended 167-179 degrees off with exit 0.
TEST(GlobalAlignment, NistRotatedHalfATurnGivesTheRightPoseOrFails) {
  const testing::Part& p = part(testing::kReal + "nist/nist_ctc_02_asme1_ap242-1.stp");
  engine::SyntheticScanOptions o;
  o.points = 8000;
  o.noise_sigma = 0.1;
  o.T_scan_model = engine::pose_from_euler_degrees(180, 0, 0, Vec3::Zero());
  const engine::SyntheticScan scan = engine::make_synthetic_scan(p.model->model(), o);
  Aligner aligner(*p.model, icp::IcpOptions{}, {}, p.features);
  const AlignmentResult r = aligner.align(scan.points);
  const Errors e = pose_error(scan.T_model_scan, r.icp.T_model_scan);
  if (r.ok()) {
    EXPECT_TRUE(r.fit.good);
    EXPECT_LT(e.degrees, 0.05);
    EXPECT_LT(e.translation, 1e-3 * p.size);
  } else {
    EXPECT_GT(e.degrees + e.translation, 0.0) << "a right pose reported as failed";
  }
}

// A scan made with `o` aligns from any pose with default options: a good fit, within 0.05 degrees
// and 5e-4 of the part's size.
void expect_right_pose(const testing::Part& p, const engine::SyntheticScanOptions& o) {
  const engine::SyntheticScan scan = engine::make_synthetic_scan(p.model->model(), o);
  Aligner aligner(*p.model, icp::IcpOptions{}, {}, p.features);
  const AlignmentResult r = aligner.align(scan.points);
  ASSERT_TRUE(r.ok()) << *r.failure;
  EXPECT_TRUE(r.fit.good);
  const Errors e = pose_error(scan.T_model_scan, r.icp.T_model_scan);
  EXPECT_LT(e.degrees, 0.05);
  EXPECT_LT(e.translation, 5e-4 * p.size);
}

// Outliers in the scan's own box (1.4 a voxel around NIST CTC-02): the voxels they alone fill
// outnumbered the surface's within a keypoint's normal radius, and the PCA kept 720 of about
// 2,800 keypoints, too few to find the pose (exit 1 on 3 of 10 such scans).
TEST(GlobalAlignment, NistWithOutliersFillingItsBox) {
  const testing::Part& p = part(testing::kReal + "nist/nist_ctc_02_asme1_ap242-1.stp");
  engine::SyntheticScanOptions o;
  o.points = 50000;
  o.noise_sigma = 1e-4 * p.size;
  o.outlier_fraction = 0.2;
  o.seed = 3;
  o.T_scan_model = engine::pose_from_euler_degrees(98.879089, 104.808221, 93.336660,
                                                   Vec3(-985.771348, -373.252453, -1109.161607));
  expect_right_pose(p, o);
}

// A 1 M-point half view of NIST CTC-02 (issue 25's benchmark, `run.py --points 1000000`, a
// half-view row's fifth pose): the keypoints of the scan's first 50,000-point subset gave no
// hypothesis near the pose in either round (best 4.4% inliers, exit 1), and a last round with
// fresh draws found it. Since the model's keypoints are described as the scan's are
// (ModelFeatures::described_keypoints) the first round finds it: a hard scan kept; the rounds
// after the first are tested below.
TEST(GlobalAlignment, AHardHalfViewOfAMillionPoints) {
  const testing::Part& p = part(testing::kReal + "nist/nist_ctc_02_asme1_ap242-1.stp");
  engine::SyntheticScanOptions o;
  o.points = 1000000;
  o.noise_sigma = 1e-4 * p.size;
  o.view_fraction = 0.5;
  o.seed = 5;
  o.T_scan_model = engine::pose_from_euler_degrees(102.630705, -73.797681, 96.757834,
                                                   Vec3(496.168793, 329.592719, -1352.954413));
  expect_right_pose(p, o);
}

// The rounds after the first: when no verified pose holds GlobalOptions::retry_inlier_fraction of
// the points, an exhaustive second round, and then a last one with fresh draws on another
// subset's keypoints (a scan above feature_points). No scan of the benchmark needs them since
// the model's keypoints are described as the scan's are, so a fraction no pose reaches forces
// them here: every round runs, the report counts all their hypotheses and speaks of the last
// round's keypoints and matches, and the best of what every round scored still wins.
TEST(GlobalAlignment, EveryRoundRunsWhenNoPoseHoldsEnoughPoints) {
  const testing::Part& p = part(testing::kReal + "occt/bearing.iges");
  engine::SyntheticScanOptions o;
  o.points = 60000;  // above feature_points: the last round draws another subset's keypoints
  o.noise_sigma = 1e-4 * p.size;
  o.seed = 11;
  o.T_scan_model = engine::pose_from_euler_degrees(-140.0, 35.0, 80.0, Vec3(0.2, -0.1, 0.15));
  const engine::SyntheticScan scan = engine::make_synthetic_scan(p.model->model(), o);
  Aligner first(*p.model, icp::IcpOptions{}, {}, p.features);
  const AlignmentResult one = first.align(scan.points);
  RegistrationOptions forced;
  forced.global.retry_inlier_fraction = 1.01;
  ASSERT_GT(scan.points.size(), forced.global.feature_points);
  Aligner every(*p.model, icp::IcpOptions{}, forced, p.features);
  const AlignmentResult all = every.align(scan.points);
  for (const AlignmentResult* r : {&one, &all}) {
    ASSERT_TRUE(r->ok()) << *r->failure;
    EXPECT_TRUE(r->fit.good);
    const Errors e = pose_error(scan.T_model_scan, r->icp.T_model_scan);
    EXPECT_LT(e.degrees, 0.05);
    EXPECT_LT(e.translation, 5e-4 * p.size);
  }
  // The second round keeps four times the first's hypotheses, the last as many again.
  EXPECT_GE(all.coarse->hypotheses, 5 * one.coarse->hypotheses)
      << one.coarse->hypotheses << " -> " << all.coarse->hypotheses;
  EXPECT_TRUE(all.coarse->scan_keypoints != one.coarse->scan_keypoints ||
              all.coarse->matches != one.coarse->matches)
      << "the report's keypoints and matches are not the last round's";
}

// Quarter views of NIST CTC-02 seen from above its flange (issue 25's benchmark, `run.py
// --conditions quarter --parts nist`, poses 9, 13, 17 and 20 of 30): the flange's rim, its
// bosses and walls. The model's keypoints were described with their exact normals and the
// scan's with PCA normals, which differ all along the rim's edges and fillets: 12-15 of about
// 5,200 matches were right, no round found the pose (best 2.6-24% inliers, exit 1). Described
// like the scan's (ModelFeatures::described_keypoints), 36-46 of about 1,950 are.
TEST(GlobalAlignment, NistQuarterViewsOfTheFlange) {
  const testing::Part& p = part(testing::kReal + "nist/nist_ctc_02_asme1_ap242-1.stp");
  struct View {
    std::uint64_t seed;
    double rx, ry, rz;
    Vec3 t;
  };
  for (const View& v :
       {View{9, 115.065619, 65.983286, 103.354899, Vec3(-954.913588, 853.873010, -585.204348)},
        View{13, -27.821913, 32.220742, -171.183356,
             Vec3(1045.538149, -402.883151, -1729.352396)}}) {
    SCOPED_TRACE(v.seed);
    engine::SyntheticScanOptions o;
    o.points = 50000;
    o.noise_sigma = 1e-4 * p.size;
    o.view_fraction = 0.25;
    o.seed = v.seed;
    o.T_scan_model = engine::pose_from_euler_degrees(v.rx, v.ry, v.rz, v.t);
    expect_right_pose(p, o);
  }
}

// Clustered clutter: a fixture plane under the part holding 30% of the points.
TEST(GlobalAlignment, PanelWithAFixturePlaneUnderIt) {
  const testing::Part& p = part(testing::kPanel);
  engine::SyntheticScanOptions o;
  o.points = 7000;
  o.noise_sigma = 1e-4 * p.size;
  const engine::SyntheticScan on_part = engine::make_synthetic_scan(p.model->model(), o);
  std::vector<Vec3> model_frame = on_part.points;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-20.0, 120.0);
  std::normal_distribution<double> g(0.0, o.noise_sigma);
  const double z = p.model->bounds().lo.z() - 5.0;
  for (int i = 0; i < 3000; ++i)
    model_frame.push_back(Vec3(u(rng), u(rng), z + g(rng)));
  std::mt19937_64 pose_rng(6);
  const Isometry3d T_scan_model = random_pose(pose_rng, p.size);
  std::vector<Vec3> scan;
  for (const Vec3& q : model_frame)
    scan.push_back(T_scan_model * q);
  Aligner aligner(*p.model, icp::IcpOptions{}, {}, p.features);
  const AlignmentResult r = aligner.align(scan);
  ASSERT_TRUE(r.ok()) << *r.failure;
  const Errors e = pose_error(T_scan_model.inverse(), r.icp.T_model_scan);
  EXPECT_LT(e.degrees, 0.05);
  EXPECT_LT(e.translation, 5e-4 * p.size);
}

// A large scan's keypoints come from a subset of it (GlobalOptions::feature_points): on all of a
// 1 M-point scan with 20% outliers the outliers fill every voxel of the scan's box, the
// keypoints' neighbourhoods see no surface, and the coarse stage's best pose put 3.9% of the
// panel's points onto it. Only the coarse stage is checked (the fine ICP runs one iteration).
TEST(GlobalAlignment, AMillionPointScanWithOutliersFindsThePose) {
  const testing::Part& p = part(testing::kPanel);
  const engine::SyntheticScan scan = scan_with_outliers(p, 1000000);
  icp::IcpOptions brief;
  brief.max_iterations = 1;
  Aligner aligner(*p.model, brief, {}, p.features);
  AlignRequest request;
  request.all_projections = false;
  const AlignmentResult r = aligner.align(scan.points, request);
  ASSERT_TRUE(r.coarse.has_value());
  EXPECT_GT(r.coarse->winner.inlier_fraction, 0.6);
  // The fine ICP's stages (fine_stage_sizes): 50,000 and 200,000 points, not a tenth and two
  // fifths (100,000 and 400,000), then all of them.
  std::vector<std::size_t> stage_points;
  for (const icp::IcpIteration& it : r.icp.log)
    stage_points.push_back(it.points);
  EXPECT_EQ(stage_points, (std::vector<std::size_t>{50000, 200000, 1000000}));
  const Errors e = pose_error(scan.T_model_scan, r.coarse->winner.T_model_scan);
  EXPECT_LT(e.degrees, 0.5);
  EXPECT_LT(e.translation, 1e-2 * p.size);
}

TEST(GlobalAlignment, SameResultForOneAndTwoThreads) {
  const testing::Part& p = part(testing::kReal + "occt/bearing.iges");
  const engine::SyntheticScan scan = scan_with_outliers(p, 6000);
  const auto run = [&](int threads) {
    tbb::task_arena arena(threads);
    return arena.execute([&] {
      // Its own features too: they are built in the arena, with its thread count.
      Aligner aligner(*p.model, icp::IcpOptions{});
      return aligner.align(scan.points);
    });
  };
  const AlignmentResult one = run(1);
  const AlignmentResult two = run(2);
  ASSERT_TRUE(one.ok());
  EXPECT_EQ(one.icp.T_model_scan.matrix(), two.icp.T_model_scan.matrix());
  EXPECT_EQ(one.coarse->winner.inlier_fraction, two.coarse->winner.inlier_fraction);
  EXPECT_EQ(one.fit.inlier_fraction, two.fit.inlier_fraction);
}

}  // namespace
}  // namespace nurbsreg::registration
