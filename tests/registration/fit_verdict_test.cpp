// The fit verdict every alignment ends with (issue 25): a wrong pose is poor and fails unless
// accepted, a right one is good with its numbers, and the noise estimate behind its tolerance
// reads the scan's own noise (within a factor 1.5) on a smooth and on a machined part.
#include <gtest/gtest.h>

#include <random>
#include <utility>
#include <vector>

#include "../../registration/src/verdict.hpp"
#include "global_support.hpp"

namespace nurbsreg::registration {
namespace {

using Eigen::Isometry3d;
using engine::Vec3;
using testing::part;

TEST(FitVerdict, AWrongPoseFromAnInitIsPoorAndFails) {
  const testing::Part& p = part(testing::kReal + "occt/bearing.iges");
  engine::SyntheticScanOptions o;
  o.points = 6000;
  o.noise_sigma = 1e-4 * p.size;
  o.T_scan_model = engine::pose_from_euler_degrees(0, 150, 0, Vec3::Zero());
  const engine::SyntheticScan scan = engine::make_synthetic_scan(p.model->model(), o);
  Aligner aligner(*p.model, icp::IcpOptions{}, {}, p.features);
  const AlignmentResult r = aligner.align(scan.points, Isometry3d::Identity());
  const testing::Errors e = testing::pose_error(scan.T_model_scan, r.icp.T_model_scan);
  ASSERT_GT(e.degrees, 1.0) << "ICP from the identity found the pose: the test needs another";
  EXPECT_FALSE(r.fit.good);
  ASSERT_TRUE(r.failure.has_value());
  EXPECT_NE(r.failure->find("poor fit"), std::string::npos) << *r.failure;
  // Accepted on request: the same pose, reported poor but not failed.
  RegistrationOptions accept;
  accept.verdict.accept_poor = true;
  Aligner lenient(*p.model, icp::IcpOptions{}, accept, p.features);
  const AlignmentResult a = lenient.align(scan.points, Isometry3d::Identity());
  EXPECT_EQ(a.icp.T_model_scan.matrix(), r.icp.T_model_scan.matrix());
  EXPECT_EQ(a.fit.good, r.fit.good);
  EXPECT_TRUE(a.ok());
}

// From a right starting pose with clutter, the ICP as given (no robust kernel) is pulled off
// by the outliers: the failure says which option fits such a scan, and that option does.
TEST(FitVerdict, APoorFitFromAnInitWithoutARobustKernelSaysWhichKernelFits) {
  const testing::Part& p = part(testing::kSymmetricAssembly);
  const engine::SyntheticScan scan = testing::cluttered_assembly_scan(50000);
  Aligner plain(*p.model, icp::IcpOptions{}, {}, p.features);
  const AlignmentResult r = plain.align(scan.points, scan.T_model_scan);
  EXPECT_FALSE(r.fit.good);
  ASSERT_TRUE(r.failure.has_value());
  EXPECT_NE(r.failure->find("no robust kernel"), std::string::npos) << *r.failure;
  icp::IcpOptions tukey;
  tukey.kernel = icp::RobustKernel::tukey;
  Aligner robust(*p.model, tukey, {}, p.features);
  const AlignmentResult t = robust.align(scan.points, scan.T_model_scan);
  ASSERT_TRUE(t.ok()) << *t.failure;
  EXPECT_TRUE(t.fit.good);
  EXPECT_LT(testing::pose_error(scan.T_model_scan, t.icp.T_model_scan).degrees, 0.01);
}

TEST(FitVerdict, ARightPoseIsGoodWithItsNumbers) {
  const testing::Part& p = part(testing::kPanel);
  engine::SyntheticScanOptions o;
  o.points = 10000;
  o.noise_sigma = 1e-4 * p.size;
  o.view_fraction = 0.25;
  const engine::SyntheticScan scan = engine::make_synthetic_scan(p.model->model(), o);
  Aligner aligner(*p.model, icp::IcpOptions{}, {}, p.features);
  const AlignmentResult r = aligner.align(scan.points, Isometry3d::Identity());
  ASSERT_TRUE(r.ok()) << *r.failure;
  EXPECT_TRUE(r.fit.good);
  EXPECT_GT(r.fit.inlier_fraction, 0.95);
  EXPECT_GT(r.fit.coverage, 0.15);
  EXPECT_LT(r.fit.coverage, 0.5);
}

// The coverage hashes a sample of a large scan's points. A fixed stride (every 5th of a million)
// aliased with synth's outliers, which replace every 5th point at 20%: it saw only outliers, and
// a right pose on a full view was judged poor for covering a few percent of the model.
TEST(FitVerdict, TheCoverageOfALargeScanSeesItsInliersWhereverTheOutliersAre) {
  const testing::Part& p = part(testing::kPanel);
  engine::SyntheticScanOptions o;
  o.points = 1000000;  // above the sample's 200,000 points: a stride of 5 before
  o.noise_sigma = 1e-4 * p.size;
  o.outlier_fraction = 0.2;
  const engine::SyntheticScan scan = engine::make_synthetic_scan(p.model->model(), o);
  icp::IcpOptions tukey;
  tukey.kernel = icp::RobustKernel::tukey;
  tukey.max_iterations = 1;
  Aligner aligner(*p.model, tukey, {}, p.features);
  AlignRequest request;
  request.init = scan.T_model_scan;
  request.all_projections = false;
  const AlignmentResult r = aligner.align(scan.points, request);
  EXPECT_TRUE(r.fit.good) << r.fit.reason;
  EXPECT_GT(r.fit.inlier_fraction, 0.75);
  EXPECT_GT(r.fit.coverage, 0.9);
}

// One iteration from the true pose of a synthetic scan (noise `relative` x the part's size): the
// estimate is the scan's own, independent of ICP.
struct NoiseCase {
  double sigma = 0.0;
  AlignmentResult result;
};
NoiseCase align_once(const testing::Part& p, std::size_t points, double relative, double outliers,
                     std::uint64_t seed) {
  engine::SyntheticScanOptions o;
  o.points = points;
  o.noise_sigma = relative * p.size;
  o.outlier_fraction = outliers;
  o.seed = seed;
  const engine::SyntheticScan scan = engine::make_synthetic_scan(p.model->model(), o);
  icp::IcpOptions one;
  one.max_iterations = 1;
  Aligner aligner(*p.model, one, {}, p.features);
  return {o.noise_sigma, aligner.align(scan.points, Isometry3d::Identity())};
}

// The estimate once read 1.6-2.7 times the noise on machined parts (a plane fit per
// neighbourhood took the fillets' and holes' curvature for noise): within 1.5 both ways, with
// and without outliers, at two noise levels.
TEST(FitVerdict, TheNoiseEstimateReadsTheScansNoise) {
  for (const std::string& path :
       {testing::kReal + "occt/bearing.iges", testing::kReal + "occt/linkrods.step"}) {
    const testing::Part& p = part(path);
    // (relative noise, outlier fraction)
    for (const auto& [relative, outliers] : {std::pair{1e-4, 0.0}, std::pair{4e-4, 0.2}}) {
      const NoiseCase c = align_once(p, 10000, relative, outliers, 3);
      SCOPED_TRACE(::testing::Message() << path << " noise " << c.sigma << " outliers " << outliers
                                        << ": estimate " << c.result.fit.scan_noise);
      EXPECT_GT(c.result.fit.scan_noise, c.sigma / 1.5);
      EXPECT_LT(c.result.fit.scan_noise, c.sigma * 1.5);
    }
  }
}

// Noise that is a large share of the neighbourhood radius: the balls were slabs as thick as
// they were wide, the surface test kept the thin ones, and the estimate read about a quarter of
// the radius whatever the noise (the IEA blade at 0.5% of its diagonal: 0.10 for 0.59, and the
// verdict called the right pose poor). The radius now grows until the estimate is well inside it.
// The blade is thin-walled: at that noise its tip's sheets are closer than the balls are wide.
TEST(FitVerdict, HeavyNoiseIsReadAndTheRightPoseIsGood) {
  for (const std::string& path :
       {testing::kReal + "occt/bearing.iges", testing::kReal + "occt/linkrods.step",
        testing::kReal + "iea-15mw/IEA_15MW_CFD.stp"}) {
    const NoiseCase c = align_once(part(path), 20000, 5e-3, 0.0, 5);
    const AlignmentResult& r = c.result;
    SCOPED_TRACE(::testing::Message()
                 << path << " noise " << c.sigma << ": estimate " << r.fit.scan_noise);
    EXPECT_GT(r.fit.scan_noise, c.sigma / 1.5);
    EXPECT_LT(r.fit.scan_noise, c.sigma * 1.5);
    EXPECT_TRUE(r.fit.good) << r.fit.reason;
  }
}

// Dense clutter in the scan's box inflates the scan's own estimate (neighbourhoods mix surface
// and clutter points): NIST CTC-02 with 30% outliers read about 4 times its noise, and the
// verdict counted clutter up to 12 sigmas from the surface as fitting. The exact distances at
// the pose read the noise; the tolerance is 3 x that.
TEST(FitVerdict, UnderDenseClutterTheDistancesAtThePoseTightenTheNoise) {
  const testing::Part& p = part(testing::kReal + "nist/nist_ctc_02_asme1_ap242-1.stp");
  engine::SyntheticScanOptions o;
  o.points = 50000;
  o.noise_sigma = 1e-4 * p.size;
  o.outlier_fraction = 0.3;
  o.seed = 4;
  const engine::SyntheticScan scan = engine::make_synthetic_scan(p.model->model(), o);
  icp::IcpOptions one;
  one.max_iterations = 1;
  one.kernel = icp::RobustKernel::tukey;
  Aligner aligner(*p.model, one, {}, p.features);
  const AlignmentResult r = aligner.align(scan.points, scan.T_model_scan);
  ASSERT_TRUE(r.fit.evaluated);
  // The case this test is about: the scan's own estimate is far off.
  ASSERT_GT(r.fit.scan_noise, 2.0 * o.noise_sigma);
  EXPECT_NEAR(r.fit.fit_noise, o.noise_sigma, 0.1 * o.noise_sigma);
  EXPECT_EQ(r.fit.noise, r.fit.fit_noise);
  EXPECT_NEAR(r.fit.tolerance, 3.0 * r.fit.fit_noise, 1e-12 * p.size);
  EXPECT_TRUE(r.fit.good) << r.fit.reason;
  // The inliers are the scan's surface points (70%), not the clutter within a wide tolerance.
  EXPECT_NEAR(r.fit.inlier_fraction, 0.7, 0.01);
  EXPECT_NEAR(r.fit.rms_ratio, 1.0, 0.1);
}

// The residuals' noise: the median of the distances within the window, read as a normal's
// truncated at three sigmas; clutter in the window raises it a little, never below the truth.
TEST(FitVerdict, TheResidualNoiseIsRobustAndNeedsEnoughPoints) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0.0, 2.0);
  std::uniform_real_distribution<double> clutter(0.0, 40.0);
  std::vector<double> clean, cluttered;
  for (int i = 0; i < 100000; ++i) {
    const double d = std::abs(normal(rng));
    clean.push_back(d);
    cluttered.push_back(i % 10 < 3 ? clutter(rng) : d);
  }
  // Window 3 sigmas (a right scan estimate): the truncation is what the constant corrects.
  EXPECT_NEAR(detail::fit_noise(clean, 6.0), 2.0, 0.03);
  // Window 12 sigmas (the estimate 4 times too high) with 30% clutter spread to 20 sigmas: 18%
  // of the points are clutter within the window (far more than in a real scan's box, where the
  // clutter near the surface is a thin share), and the noise reads about 30% high, still a
  // third of the scan estimate's.
  const double with_clutter = detail::fit_noise(cluttered, 24.0);
  EXPECT_GT(with_clutter, 2.0);
  EXPECT_LT(with_clutter, 2.7);
  // A misfit (residuals of sigma 2 in a window made for 1): larger than the window's noise, so
  // judge_fit keeps the scan's.
  EXPECT_GT(detail::fit_noise(clean, 3.0), 1.0);
  // Too few points within the window: none.
  const std::vector<double> few(clean.begin(), clean.begin() + 99);
  EXPECT_EQ(detail::fit_noise(few, 1e9), 0.0);
  EXPECT_GT(detail::fit_noise(std::vector<double>(clean.begin(), clean.begin() + 100), 1e9), 0.0);
}

}  // namespace
}  // namespace nurbsreg::registration
