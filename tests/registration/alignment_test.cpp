// registration::Aligner, the one alignment call behind align, batch, the service and Python:
// the pose against the known one of a synthetic scan, the deviation summary against a sort, the
// failure line when ICP loses its correspondences, and warm reuse over frames.
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "nurbsreg/registration/alignment.hpp"
#include "support/log_capture.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::registration {
namespace {

using Eigen::Isometry3d;
using engine::Vec3;

const engine::PreparedModel& panel() {
  static const engine::PreparedModel model(
      io::read_model_json(nurbsreg::test::examples_dir() + "/panel.json"));
  return model;
}

Isometry3d true_pose(double size) {
  Isometry3d T = Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(4.0 * std::numbers::pi / 180.0, Vec3(1, 2, 3).normalized())
                   .toRotationMatrix();
  T.translation() = Vec3(3.0, -2.0, 4.0).normalized() * 0.03 * size;
  return T;
}

engine::SyntheticScan scan_of(const engine::PreparedModel& model, std::size_t points, double noise,
                              std::uint64_t seed) {
  engine::SyntheticScanOptions o;
  o.points = points;
  o.noise_sigma = noise;
  o.T_scan_model = true_pose(model.bounds().diagonal()).inverse();
  o.seed = seed;
  return engine::make_synthetic_scan(model.model(), o);
}

TEST(DeviationSummary, QuantilesAreThoseOfTheSortedValues) {
  std::mt19937_64 rng(7);
  std::exponential_distribution<double> dist(3.0);
  std::vector<double> values(1001);
  for (double& v : values)
    v = dist(rng);
  const DeviationSummary d = summarise_deviations(values);
  std::vector<double> sorted = values;
  std::sort(sorted.begin(), sorted.end());
  double sum = 0, sum_sq = 0;
  for (double v : values) {
    sum += v;
    sum_sq += v * v;
  }
  EXPECT_EQ(d.count, 1001u);
  EXPECT_EQ(d.p50, sorted[500]);
  EXPECT_EQ(d.p95, sorted[950]);
  EXPECT_EQ(d.p99, sorted[990]);
  EXPECT_EQ(d.max, sorted.back());
  EXPECT_NEAR(d.mean, sum / 1001.0, 1e-12);
  EXPECT_NEAR(d.rms, std::sqrt(sum_sq / 1001.0), 1e-12);
  EXPECT_EQ(summarise_deviations({}).count, 0u);
}

// From any pose the fine ICP's stages are a tenth and two fifths of the scan up to 500,000 points
// (as they always were); a larger scan's stay at 50,000 points and at least a fifth of it: the
// certificates of 50,000 points cover a part as well, and from a fifth the first full step is
// small enough for the second full pass to stop.
TEST(Aligner, TheFineStagesOfALargeScanAreBounded) {
  using Sizes = std::vector<std::size_t>;
  EXPECT_EQ(fine_stage_sizes(4000), Sizes{});
  EXPECT_EQ(fine_stage_sizes(10000), Sizes{4000});
  EXPECT_EQ(fine_stage_sizes(50000), (Sizes{5000, 20000}));
  EXPECT_EQ(fine_stage_sizes(500000), (Sizes{50000, 200000}));
  EXPECT_EQ(fine_stage_sizes(1000000), (Sizes{50000, 200000}));
  EXPECT_EQ(fine_stage_sizes(2000000), (Sizes{50000, 400000}));
}

TEST(Aligner, RecoversTheKnownPoseAndSummarisesTheExactDeviations) {
  const engine::PreparedModel& model = panel();
  const double noise = 1e-4 * model.bounds().diagonal();
  const engine::SyntheticScan scan = scan_of(model, 5000, noise, 3);
  Aligner aligner(model, icp::IcpOptions{});
  const AlignmentResult r = aligner.align(scan.points, Isometry3d::Identity());
  ASSERT_TRUE(r.ok()) << *r.failure;
  const Isometry3d error = true_pose(model.bounds().diagonal()) * r.icp.T_model_scan.inverse();
  EXPECT_LT(Eigen::AngleAxisd(error.linear()).angle(), 1e-3);
  EXPECT_LT(error.translation().norm(), 10 * noise);
  ASSERT_EQ(r.aligned.size(), scan.points.size());
  // The deviations are the exact distances of the aligned points: at the noise level.
  EXPECT_EQ(r.deviation.count, scan.points.size());
  EXPECT_LT(r.deviation.rms, 2 * noise);
  EXPECT_GT(r.deviation.rms, 0.5 * noise);
  const engine::ProjectionResults& proj = aligner.last_projections();
  ASSERT_EQ(proj.distance.size(), scan.points.size());
  std::vector<double> distances(proj.distance.begin(), proj.distance.end());
  EXPECT_EQ(summarise_deviations(distances).p95, r.deviation.p95);
  // The model's size is its trimmed faces' box (PreparedModel::geometry_bounds).
  EXPECT_EQ(r.sizes.model, model.geometry_bounds().box.diagonal());
}

TEST(Aligner, ReusedOverFramesGivesTheSamePoseAsAFreshOne) {
  const engine::PreparedModel& model = panel();
  const double noise = 1e-4 * model.bounds().diagonal();
  const engine::SyntheticScan first = scan_of(model, 3000, noise, 11);
  const engine::SyntheticScan second = scan_of(model, 4000, noise, 12);
  Aligner reused(model, icp::IcpOptions{});
  (void)reused.align(first.points, Isometry3d::Identity());
  const AlignmentResult warm = reused.align(second.points, Isometry3d::Identity());
  Aligner fresh(model, icp::IcpOptions{});
  const AlignmentResult cold = fresh.align(second.points, Isometry3d::Identity());
  EXPECT_TRUE(warm.icp.T_model_scan.matrix().isApprox(cold.icp.T_model_scan.matrix(), 1e-9));
}

// AlignRequest::all_projections false bounds the final pass by the deviation summary's distance
// (and the verdict's tolerance): the pose, the summary and the verdict are those of the full
// pass, the points near the model keep their exact distances, and only far ones go unanswered.
void expect_same_answers_without_far_projections(const engine::PreparedModel& model,
                                                 std::span<const Vec3> scan,
                                                 const icp::IcpOptions& options,
                                                 const AlignRequest& request,
                                                 double deviation_distance) {
  Aligner full(model, options);
  const AlignmentResult a = full.align(scan, request);
  AlignRequest near_only = request;
  near_only.all_projections = false;
  Aligner bounded(model, options);
  const AlignmentResult b = bounded.align(scan, near_only);
  ASSERT_TRUE(a.ok()) << *a.failure;
  ASSERT_TRUE(b.ok()) << *b.failure;
  EXPECT_EQ(a.icp.T_model_scan.matrix(), b.icp.T_model_scan.matrix());
  EXPECT_EQ(a.deviation.count, b.deviation.count);
  EXPECT_EQ(a.deviation.mean, b.deviation.mean);
  EXPECT_EQ(a.deviation.rms, b.deviation.rms);
  EXPECT_EQ(a.deviation.p50, b.deviation.p50);
  EXPECT_EQ(a.deviation.p99, b.deviation.p99);
  EXPECT_EQ(a.deviation.max, b.deviation.max);
  EXPECT_EQ(a.fit.good, b.fit.good);
  EXPECT_EQ(a.fit.inlier_fraction, b.fit.inlier_fraction);
  EXPECT_EQ(a.fit.rms, b.fit.rms);
  EXPECT_EQ(a.fit.coverage, b.fit.coverage);
  const engine::ProjectionResults& pa = full.last_projections();
  const engine::ProjectionResults& pb = bounded.last_projections();
  ASSERT_EQ(pa.size(), scan.size());
  ASSERT_EQ(pb.size(), scan.size());
  const double bound = std::max(deviation_distance, a.fit.tolerance);
  std::size_t unanswered = 0;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    EXPECT_EQ(pa.status[i], engine::ProjectionStatus::ok);
    if (pa.distance[i] <= bound) {
      ASSERT_EQ(pb.status[i], engine::ProjectionStatus::ok) << i;
      EXPECT_EQ(pa.distance[i], pb.distance[i]) << i;
    } else {
      unanswered += pb.status[i] != engine::ProjectionStatus::ok;
    }
  }
  EXPECT_GT(unanswered, 0u);  // the outliers beyond the bound were not projected
}

engine::SyntheticScan cluttered_scan_of(const engine::PreparedModel& model, std::size_t points,
                                        double noise, std::uint64_t seed) {
  engine::SyntheticScanOptions o;
  o.points = points;
  o.noise_sigma = noise;
  o.outlier_fraction = 0.2;
  o.T_scan_model = true_pose(model.bounds().diagonal()).inverse();
  o.seed = seed;
  return engine::make_synthetic_scan(model.model(), o);
}

// The panel scanned from a far pose with 20% outliers, noise 1e-4 of its size: the tests of the
// alignment from any pose below.
engine::SyntheticScan cluttered_panel_scan() {
  const engine::PreparedModel& model = panel();
  return cluttered_scan_of(model, 4000, 1e-4 * model.bounds().diagonal(), 22);
}

TEST(Aligner, WithoutFarProjectionsFromAPoseTheSummaryAndVerdictAreTheSame) {
  const engine::PreparedModel& model = panel();
  const double noise = 1e-4 * model.bounds().diagonal();
  const engine::SyntheticScan scan = cluttered_scan_of(model, 4000, noise, 21);
  icp::IcpOptions options;
  options.kernel = icp::RobustKernel::tukey;
  options.max_correspondence_distance = 0.01 * model.bounds().diagonal();
  AlignRequest request;
  request.init = Isometry3d::Identity();
  expect_same_answers_without_far_projections(model, scan.points, options, request,
                                              options.max_correspondence_distance);
}

TEST(Aligner, WithoutFarProjectionsFromAnyPoseTheSummaryAndVerdictAreTheSame) {
  const engine::PreparedModel& model = panel();
  const engine::SyntheticScan scan = cluttered_panel_scan();
  AlignRequest request;
  request.global = GlobalMode::on;
  // The fine ICP after the global stage bounds its distances itself (GlobalOptions).
  Aligner probe(model, icp::IcpOptions{});
  const double fine_distance = GlobalOptions{}.fine_max_distance_voxels * probe.features().voxel();
  expect_same_answers_without_far_projections(model, scan.points, icp::IcpOptions{}, request,
                                              fine_distance);
}

// From any pose, the fine ICP's last pass (at the returned pose, bounded by its distance, which
// is beyond the verdict's tolerance) is the deviations' and the verdict's: when nobody reads the
// far points' projections no projection follows it, and with every projection asked for only
// the points it left unanswered are projected (the reports are the same bits: above).
TEST(Aligner, FromAnyPoseTheVerdictReadsTheFineIcpsLastPass) {
  const engine::PreparedModel& model = panel();
  const engine::SyntheticScan scan = cluttered_panel_scan();
  // The points of every projection after the fine ICP's, from the `-v` lines.
  const auto passes_after_the_fine_icp = [&](bool all_projections) {
    AlignRequest request;
    request.global = GlobalMode::on;
    request.all_projections = all_projections;
    Aligner aligner(model, icp::IcpOptions{});
    AlignmentResult r;
    const std::vector<std::string> lines =
        test::log_lines_of(spdlog::level::debug, [&] { r = aligner.align(scan.points, request); });
    EXPECT_TRUE(r.ok()) << r.failure.value_or("");
    EXPECT_TRUE(r.icp.statistics_at_pose);
    auto line = std::find_if(lines.begin(), lines.end(), [](const std::string& l) {
      return l.starts_with("align: fine ICP in");
    });
    EXPECT_NE(line, lines.end());
    std::vector<std::size_t> points;
    for (; line != lines.end(); ++line) {
      if (line->starts_with("find ")) points.push_back(std::stoul(line->substr(5)));
    }
    return points;
  };
  EXPECT_TRUE(passes_after_the_fine_icp(false).empty());
  const std::vector<std::size_t> far = passes_after_the_fine_icp(true);
  ASSERT_EQ(far.size(), 1u);
  EXPECT_GT(far.front(), 0u);                  // the outliers beyond the ICP's bound
  EXPECT_LT(far.front(), scan.points.size());  // not every point
}

// From any pose the fine ICP and the verdict work on the scan in spatial order: what comes back
// is in the scan's own order. Every aligned point is T * its scan point (the same bits), and
// every projection is that point's own exact closest point (a cold projection of it gives the
// same distance and face).
TEST(Aligner, FromAnyPoseThePointsComeBackInScanOrder) {
  const engine::PreparedModel& model = panel();
  const engine::SyntheticScan scan = cluttered_panel_scan();
  AlignRequest request;
  request.global = GlobalMode::on;
  Aligner aligner(model, icp::IcpOptions{});
  const AlignmentResult r = aligner.align(scan.points, request);
  ASSERT_TRUE(r.ok()) << *r.failure;
  ASSERT_EQ(r.aligned.size(), scan.points.size());
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    const Vec3 expected = r.icp.T_model_scan * scan.points[i];
    ASSERT_EQ(r.aligned[i], expected) << i;
  }
  const engine::ProjectionResults& answers = aligner.last_projections();
  ASSERT_EQ(answers.size(), scan.points.size());
  engine::Projector cold(model);
  engine::ProjectionResults reference;
  cold.project(engine::PointView::of(r.aligned), engine::ProjectionOptions{}, reference);
  const double tolerance = 1e-12 * model.bounds().diagonal();
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    ASSERT_EQ(answers.status[i], engine::ProjectionStatus::ok) << i;
    EXPECT_NEAR(answers.distance[i], reference.distance[i], tolerance) << i;
    EXPECT_EQ(answers.entity[i], reference.entity[i]) << i;
    EXPECT_NEAR(std::abs(answers.signed_distance[i]), answers.distance[i], tolerance) << i;
  }
}

// From any pose the projections go back to scan order when first asked for: an aligner reused
// for a frame from a pose then serves that frame's, whether the earlier ones were asked for or
// not, and a later frame from any pose its own.
TEST(Aligner, ReusedAcrossModesServesTheLastFramesProjections) {
  const engine::PreparedModel& model = panel();
  const engine::SyntheticScan cluttered = cluttered_panel_scan();
  const double noise = 1e-4 * model.bounds().diagonal();
  const engine::SyntheticScan posed = scan_of(model, 3000, noise, 21);
  AlignRequest global;
  global.global = GlobalMode::on;
  const auto same = [](const engine::ProjectionResults& a, const engine::ProjectionResults& b) {
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      ASSERT_EQ(a.distance[i], b.distance[i]) << i;
      ASSERT_EQ(a.entity[i], b.entity[i]) << i;
    }
  };
  Aligner fresh_global(model, icp::IcpOptions{});
  ASSERT_TRUE(fresh_global.align(cluttered.points, global).ok());
  Aligner fresh_posed(model, icp::IcpOptions{});
  ASSERT_TRUE(fresh_posed.align(posed.points, Isometry3d::Identity()).ok());

  for (const bool read_first : {false, true}) {
    Aligner reused(model, icp::IcpOptions{});
    ASSERT_TRUE(reused.align(cluttered.points, global).ok());
    if (read_first) same(reused.last_projections(), fresh_global.last_projections());
    ASSERT_TRUE(reused.align(posed.points, Isometry3d::Identity()).ok());
    same(reused.last_projections(), fresh_posed.last_projections());
    ASSERT_TRUE(reused.align(cluttered.points, global).ok());
    same(reused.last_projections(), fresh_global.last_projections());
  }
}

// AlignRequest::progress: from any pose it gets the coarse stage's outcome when that stage ends
// (then the fine ICP's lines, at most about one a second: none for this short alignment); the
// answer is the same with and without it; from a pose there is no coarse line.
TEST(Aligner, ProgressSaysWhereALongAlignmentIs) {
  const engine::PreparedModel& model = panel();
  const engine::SyntheticScan scan = cluttered_panel_scan();
  AlignRequest request;
  request.global = GlobalMode::on;
  std::vector<std::string> lines;
  request.progress = [&](const std::string& line) { lines.push_back(line); };
  Aligner aligner(model, icp::IcpOptions{});
  const AlignmentResult with = aligner.align(scan.points, request);
  ASSERT_TRUE(with.ok()) << with.failure.value_or("");
  ASSERT_FALSE(lines.empty());
  EXPECT_TRUE(lines.front().starts_with("coarse alignment: a pose in ")) << lines.front();
  EXPECT_NE(lines.front().find("fine ICP on 4000 points next"), std::string::npos) << lines.front();
  for (std::size_t k = 1; k < lines.size(); ++k)
    EXPECT_TRUE(lines[k].starts_with("fine ICP: ")) << lines[k];
  AlignRequest quiet = request;
  quiet.progress = nullptr;
  const AlignmentResult without = Aligner(model, icp::IcpOptions{}).align(scan.points, quiet);
  EXPECT_EQ(without.icp.T_model_scan.matrix(), with.icp.T_model_scan.matrix());
  // The callback is this call's only: the next call without one says nothing to it.
  const std::size_t said = lines.size();
  aligner.align(scan.points, quiet);
  EXPECT_EQ(lines.size(), said);
  // From a pose: ICP lines only (none here: it is short; plain ICP on this cluttered scan
  // fits poorly, which does not matter here).
  AlignRequest from_pose = request;
  from_pose.global = GlobalMode::automatic;
  from_pose.init = with.icp.T_model_scan;
  lines.clear();
  aligner.align(scan.points, from_pose);
  for (const std::string& line : lines)
    EXPECT_TRUE(line.starts_with("ICP: ")) << line;
}

TEST(Aligner, AScanFarFromTheModelFailsWithAReason) {
  const engine::PreparedModel& model = panel();
  const engine::SyntheticScan scan = scan_of(model, 2000, 0.0, 5);
  icp::IcpOptions options;
  options.max_correspondence_distance = 1e-3 * model.bounds().diagonal();
  Aligner aligner(model, options);
  Isometry3d far = Isometry3d::Identity();
  far.translation() = Vec3(0, 0, 10 * model.bounds().diagonal());
  const AlignmentResult r = aligner.align(scan.points, far);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.failure->find("alignment failed"), std::string::npos) << *r.failure;
  EXPECT_NE(r.failure->find("--max-distance"), std::string::npos) << *r.failure;
}

TEST(Aligner, InvalidOptionsAreRejectedByName) {
  icp::IcpOptions options;
  options.keep_fraction = 0.0;
  EXPECT_THROW(Aligner(panel(), options), std::invalid_argument);
}

}  // namespace
}  // namespace nurbsreg::registration
