// ICP against analytic scenes whose closest points are exact (planes, spheres, cylinders), so
// every error below is the solver's own. Scene size S = 100 model units; the known pose is a
// 5 degree rotation and a 5 unit (5% of S) translation.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <numbers>
#include <random>

#include <Eigen/SVD>

#include "nurbsreg/icp/analytic.hpp"
#include "nurbsreg/icp/icp.hpp"

namespace nurbsreg::icp {
namespace {

using Eigen::Isometry3d;
using engine::Vec3;

constexpr double kSize = 100.0;

Isometry3d make_pose(const Vec3& axis, double degrees, const Vec3& translation) {
  Isometry3d T = Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(degrees * std::numbers::pi / 180.0, axis.normalized()).matrix();
  T.translation() = translation;
  return T;
}

// The pose used throughout: 5 degrees about a generic axis, translation of length 5.
Isometry3d true_pose() {
  return make_pose(Vec3(1.0, 2.0, 3.0), 5.0, Vec3(3.0, -2.0, 4.0).normalized() * 0.05 * kSize);
}

// A plane with three spheres on it: every rigid motion changes some distance.
std::vector<Primitive> scene() {
  Rectangle floor;
  floor.half_u = floor.half_v = 0.5 * kSize;
  return {floor, Sphere{Vec3(-25, -20, 14), 12}, Sphere{Vec3(28, -15, 10), 8},
          Sphere{Vec3(0, 28, 17), 15}};
}

// Model samples -> scan frame: scan = T_true^-1 * model, so model = T_true * scan.
std::vector<Vec3> to_scan(const std::vector<Vec3>& model_points, const Isometry3d& T_true) {
  std::vector<Vec3> scan;
  scan.reserve(model_points.size());
  const Isometry3d inverse = T_true.inverse();
  for (const Vec3& p : model_points)
    scan.push_back(inverse * p);
  return scan;
}

// Box-Muller on std::mt19937_64 (platform-independent, unlike std::normal_distribution).
double gaussian(std::mt19937_64& rng) {
  const double u1 = (static_cast<double>(rng() >> 11) + 0.5) * 0x1.0p-53;
  const double u2 = static_cast<double>(rng() >> 11) * 0x1.0p-53;
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

void add_noise(std::vector<Vec3>& points, double sigma, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  for (Vec3& p : points) {
    const double x = gaussian(rng), y = gaussian(rng), z = gaussian(rng);
    p += sigma * Vec3(x, y, z);
  }
}

// Error of an estimate as the left twist xi with T_true = exp(xi) T_est (model frame).
Vec6 pose_error(const Isometry3d& T_est, const Isometry3d& T_true) {
  return log_se3(T_true * T_est.inverse());
}

double rotation_error(const Isometry3d& T_est, const Isometry3d& T_true) {
  return rotation_angle(T_true * T_est.inverse());
}

// Largest displacement of a scene point (|x| <= S) between the two poses' images.
double translation_error(const Isometry3d& T_est, const Isometry3d& T_true) {
  return (T_true * T_est.inverse()).translation().norm();
}

IcpOptions exact_options() {
  IcpOptions o;
  o.max_iterations = 60;
  return o;
}

TEST(Icp, PointToPlaneRecoversThePoseExactly) {
  const std::vector<Primitive> primitives = scene();
  UnionFinder finder(primitives);
  const std::vector<Vec3> scan = to_scan(sample_uniform(primitives, 4000, 7), true_pose());
  const IcpResult r = align(finder, scan, Isometry3d::Identity(), exact_options());
  ASSERT_EQ(r.termination, IcpTermination::converged) << r.brief_report();
  EXPECT_LT(rotation_error(r.T_model_scan, true_pose()), 1e-9);
  EXPECT_LT(translation_error(r.T_model_scan, true_pose()), 1e-9 * kSize);
  EXPECT_LT(r.rms, 1e-9 * kSize);
  EXPECT_EQ(r.inliers, scan.size());
  EXPECT_EQ(r.points, scan.size());
  EXPECT_FALSE(r.degeneracy.degenerate()) << r.degeneracy.describe();
  EXPECT_LT(r.iterations, 20);
  ASSERT_EQ(static_cast<int>(r.log.size()), r.iterations);
  // Gauss-Newton on a zero-residual problem: the RMS falls by orders of magnitude per step.
  EXPECT_LT(r.log[2].rms, 1e-2 * r.log[0].rms);
  EXPECT_FALSE(r.brief_report().empty());
}

// IcpOptions::on_iteration sees every iteration as the log records it, in order, and changes
// nothing.
TEST(Icp, OnIterationSeesEveryIterationOfTheLog) {
  const std::vector<Primitive> primitives = scene();
  UnionFinder finder(primitives);
  const std::vector<Vec3> scan = to_scan(sample_uniform(primitives, 4000, 7), true_pose());
  IcpOptions o = exact_options();
  std::vector<IcpIteration> seen;
  o.on_iteration = [&](const IcpIteration& it) { seen.push_back(it); };
  const IcpResult r = align(finder, scan, Isometry3d::Identity(), o);
  const IcpResult plain = align(finder, scan, Isometry3d::Identity(), exact_options());
  ASSERT_EQ(seen.size(), r.log.size());
  for (std::size_t k = 0; k < seen.size(); ++k) {
    EXPECT_EQ(seen[k].points, r.log[k].points);
    EXPECT_EQ(seen[k].rms, r.log[k].rms);
    EXPECT_EQ(seen[k].step_sigmas, r.log[k].step_sigmas);
  }
  EXPECT_EQ(r.T_model_scan.matrix(), plain.T_model_scan.matrix());
}

TEST(Icp, PointToPointRecoversThePose) {
  const std::vector<Primitive> primitives = scene();
  UnionFinder finder(primitives);
  const std::vector<Vec3> scan = to_scan(sample_uniform(primitives, 4000, 8), true_pose());
  IcpOptions o = exact_options();
  o.method = IcpMethod::point_to_point;
  o.max_iterations = 400;  // point-to-point converges linearly (Besl & McKay 1992, Thm. 1)
  o.rotation_tolerance = 1e-12;
  o.translation_tolerance = 1e-12 * kSize;
  o.relative_rms_tolerance = 0.0;
  const IcpResult r = align(finder, scan, Isometry3d::Identity(), o);
  EXPECT_EQ(r.termination, IcpTermination::converged) << r.brief_report();
  EXPECT_LT(rotation_error(r.T_model_scan, true_pose()), 1e-7);
  EXPECT_LT(translation_error(r.T_model_scan, true_pose()), 1e-7 * kSize);
}

// Independent reference for the noise test: the Fisher information of the point-to-plane
// problem at the true pose, from the true geometry (normals computed here from the scene
// definition, not by the finder). For isotropic noise of std sigma per coordinate the
// residual n . (q - f) has std sigma, so the least-squares pose error xi (left twist about
// the origin) has covariance sigma^2 (sum J J^T)^-1, J = [x x n ; n] (Gauss-Markov); each
// component therefore lies within 5 of its standard deviations (that any of the six does not
// has probability < 4e-6), and xi^T Cov^-1 xi follows chi^2 with 6 degrees of freedom
// (99.99% quantile: 27.86).
Mat6 reference_covariance(const std::vector<Vec3>& model_points, double sigma) {
  Mat6 H = Mat6::Zero();
  for (const Vec3& x : model_points) {
    Vec3 n = Vec3::UnitZ();
    for (const Primitive& p : scene()) {
      if (const Sphere* s = std::get_if<Sphere>(&p)) {
        if (std::abs((x - s->center).norm() - s->radius) < 1e-9) n = (x - s->center).normalized();
      }
    }
    Vec6 J;
    J << x.cross(n), n;
    H += J * J.transpose();
  }
  return sigma * sigma * H.inverse();
}

TEST(Icp, GaussianNoiseStaysWithinTheDerivedBound) {
  const std::vector<Primitive> primitives = scene();
  UnionFinder finder(primitives);
  const double sigma = 1e-3 * kSize;
  const std::vector<Vec3> model_points = sample_uniform(primitives, 4000, 9);
  std::vector<Vec3> scan = to_scan(model_points, true_pose());
  add_noise(scan, sigma, 10);
  const IcpResult r = align(finder, scan, Isometry3d::Identity(), exact_options());
  ASSERT_EQ(r.termination, IcpTermination::converged) << r.brief_report();
  const Mat6 cov = reference_covariance(model_points, sigma);
  const Vec6 xi = pose_error(r.T_model_scan, true_pose());
  for (int j = 0; j < 6; ++j) {
    EXPECT_LT(std::abs(xi(j)), 5.0 * std::sqrt(cov(j, j))) << "component " << j;
    // The solver's own covariance estimate agrees with the reference (sigma^2 estimated
    // from the residuals: relative error ~ 1/sqrt(2N) ~ 1%, plus small curvature effects).
    EXPECT_NEAR(r.covariance(j, j), cov(j, j), 0.1 * cov(j, j)) << "component " << j;
  }
  EXPECT_LT(xi.dot(cov.ldlt().solve(xi)), 27.86);
  // The RMS of the point-to-surface distance is the normal part of the noise: sigma.
  EXPECT_NEAR(r.rms, sigma, 0.05 * sigma);
}

struct RobustCase {
  const char* name;
  RobustKernel kernel;
  double keep_fraction;
};

class IcpOutliers : public ::testing::TestWithParam<RobustCase> {};

// The scene's 4000 samples with 10% of them replaced by uniform points in a box around it, in
// the scan frame, with noise 1e-3 S; cov: the clean problem's pose covariance.
struct OutlierScene {
  std::vector<Primitive> primitives = scene();
  std::vector<Vec3> scan;
  Mat6 cov;
};

// exact_options with the case's kernel and trimming, and room to converge.
IcpOptions robust_options(const RobustCase& c) {
  IcpOptions o = exact_options();
  o.kernel = c.kernel;
  o.keep_fraction = c.keep_fraction;
  o.max_iterations = 100;
  return o;
}

OutlierScene outlier_scene() {
  OutlierScene out;
  const double sigma = 1e-3 * kSize;
  std::vector<Vec3> model_points = sample_uniform(out.primitives, 4000, 11);
  out.cov = reference_covariance(model_points, sigma);
  std::mt19937_64 rng(12);
  const auto uniform = [&](double lo, double hi) {
    return lo + (hi - lo) * static_cast<double>(rng() >> 11) * 0x1.0p-53;
  };
  for (std::size_t i = 0; i < model_points.size(); i += 10) {
    model_points[i] = Vec3(uniform(-60, 60), uniform(-60, 60), uniform(-20, 50));
  }
  out.scan = to_scan(model_points, true_pose());
  add_noise(out.scan, sigma, 13);
  return out;
}

// 10% of the points replaced by uniform points in a box around the scene. Outliers far from
// the surfaces get weight ~0 (Tukey, Geman-McClure), bounded influence (Huber) or are trimmed;
// the few that land within a few sigma of a surface act like extra noisy inliers. Bound:
// 10 standard deviations of the clean problem (efficiency loss of the kernels <= 5%, the
// rest is the bias of the near-surface outliers, which the test keeps few).
TEST_P(IcpOutliers, RobustSettingsConverge) {
  const RobustCase c = GetParam();
  const OutlierScene scene_10 = outlier_scene();
  UnionFinder finder(scene_10.primitives);
  const std::vector<Vec3>& scan = scene_10.scan;
  const Mat6& cov = scene_10.cov;
  IcpOptions o = robust_options(c);
  const IcpResult r = align(finder, scan, Isometry3d::Identity(), o);
  ASSERT_EQ(r.termination, IcpTermination::converged) << r.brief_report();
  const Vec6 xi = pose_error(r.T_model_scan, true_pose());
  for (int j = 0; j < 6; ++j) {
    EXPECT_LT(std::abs(xi(j)), 10.0 * std::sqrt(cov(j, j))) << "component " << j;
  }
}

INSTANTIATE_TEST_SUITE_P(Kernels, IcpOutliers,
                         ::testing::Values(RobustCase{"tukey", RobustKernel::tukey, 1.0},
                                           RobustCase{"huber_trimmed", RobustKernel::huber, 0.85},
                                           RobustCase{"geman_mcclure", RobustKernel::geman_mcclure,
                                                      1.0},
                                           RobustCase{"trimmed", RobustKernel::none, 0.85}),
                         [](const auto& info) { return std::string(info.param.name); });

// IcpOptions::robust_newton: the same estimate as the IRLS steps (both stop within the
// statistical tolerance of it), reached in fewer iterations: IRLS shrinks each step by only
// 1 - E[psi'] / E[w] (0.17 for Tukey's kernel with Gaussian noise), the curvature step by about
// 0.01. From 5 degrees and 5% of the scene off with 10% outliers: the first steps, far from the
// optimum, stay IRLS ones (a curvature step there overshoots).
TEST_P(IcpOutliers, RobustNewtonStepsReachTheSameEstimateSooner) {
  const RobustCase c = GetParam();
  if (c.kernel == RobustKernel::none) GTEST_SKIP() << "no kernel: the steps are Gauss-Newton";
  const OutlierScene scene_10 = outlier_scene();
  UnionFinder finder(scene_10.primitives);
  const std::vector<Vec3>& scan = scene_10.scan;
  const Mat6& cov = scene_10.cov;
  IcpOptions o = robust_options(c);
  // Only the statistical test ends the iteration: the other two would stop IRLS early.
  o.rotation_tolerance = 0.0;
  o.relative_rms_tolerance = 0.0;
  const IcpResult irls = align(finder, scan, Isometry3d::Identity(), o);
  o.robust_newton = true;
  const IcpResult newton = align(finder, scan, Isometry3d::Identity(), o);
  ASSERT_EQ(irls.termination, IcpTermination::converged) << irls.brief_report();
  ASSERT_EQ(newton.termination, IcpTermination::converged) << newton.brief_report();
  const Vec6 apart = pose_error(newton.T_model_scan, irls.T_model_scan);
  for (int j = 0; j < 6; ++j) {
    EXPECT_LT(std::abs(apart(j)), 0.3 * std::sqrt(cov(j, j))) << "component " << j;
  }
  // Geman-McClure's curvature is negative for most residuals (|r| > s / sqrt(3)): its share
  // stays below the gate, and the steps stay IRLS ones.
  if (c.kernel == RobustKernel::geman_mcclure) {
    EXPECT_EQ(newton.iterations, irls.iterations);
    return;
  }
  // Trimming (keep_fraction) changes the inlier set from one iteration to the next, so the
  // objective itself moves a little each step, and how fast the last steps shrink depends on
  // the rounding of which points are trimmed (it differs between optimised and sanitizer
  // builds): there, no more iterations than IRLS.
  if (c.keep_fraction < 1.0) {
    EXPECT_LE(newton.iterations, irls.iterations);
    return;
  }
  EXPECT_LT(newton.iterations, irls.iterations)
      << "IRLS " << irls.iterations << ", curvature " << newton.iterations;
  // The last steps: IRLS contracts slowly (Tukey: by about 0.17), the curvature steps fast.
  const auto last_rate = [](const IcpResult& r) {
    const std::size_t n = r.log.size();
    return n < 2 ? 0.0 : r.log[n - 1].step_sigmas / r.log[n - 2].step_sigmas;
  };
  EXPECT_LT(last_rate(newton), 0.05);
  EXPECT_GT(last_rate(irls), 0.1);
}

TEST(Icp, PartialViewConverges) {
  const std::vector<Primitive> primitives = scene();
  UnionFinder finder(primitives);
  // The corner x >= 0, y >= -10 of the scene: half of one sphere, a cap of another and
  // 30% of the floor, about 30% of the scene's area.
  const std::vector<Vec3> all = sample_uniform(primitives, 10000, 14);
  std::vector<Vec3> view;
  for (const Vec3& p : all) {
    if (p.x() >= 0.0 && p.y() >= -10.0) view.push_back(p);
  }
  const double fraction = static_cast<double>(view.size()) / static_cast<double>(all.size());
  ASSERT_GT(fraction, 0.25);
  ASSERT_LT(fraction, 0.35);
  const std::vector<Vec3> scan = to_scan(view, true_pose());
  const IcpResult r = align(finder, scan, Isometry3d::Identity(), exact_options());
  ASSERT_EQ(r.termination, IcpTermination::converged) << r.brief_report();
  EXPECT_LT(rotation_error(r.T_model_scan, true_pose()), 1e-9);
  EXPECT_LT(translation_error(r.T_model_scan, true_pose()), 1e-9 * kSize);
}

TEST(Icp, ScanBeyondTheModelEdgeIsRejectedAtTheBoundary) {
  // The scan saw more floor than the model has: the model floor is 80 x 80, the scanned one
  // 100 x 100. Points beyond the edge have feet clamped to it, which pull the scan sideways
  // unless such boundary pairs are rejected. (The model edge keeps clear of the spheres so
  // that the extra floor's nearest model surface is that edge, not a sphere.)
  const std::vector<Primitive> scanned = scene();
  std::vector<Primitive> model = scanned;
  std::get<Rectangle>(model[0]).half_u = std::get<Rectangle>(model[0]).half_v = 40.0;
  UnionFinder finder(model);
  const std::vector<Vec3> scan = to_scan(sample_uniform(scanned, 4000, 24), true_pose());
  const IcpResult r = align(finder, scan, Isometry3d::Identity(), exact_options());
  ASSERT_EQ(r.termination, IcpTermination::converged) << r.brief_report();
  EXPECT_LT(rotation_error(r.T_model_scan, true_pose()), 1e-9);
  EXPECT_LT(translation_error(r.T_model_scan, true_pose()), 1e-9 * kSize);
  EXPECT_LT(r.inliers, scan.size());
  // Point-to-plane hardly notices the boundary pairs here (the extra floor is coplanar with
  // the model's, so their residual n . (q - f) is 0); point-to-point is pulled by them.
  IcpOptions p2p = exact_options();
  p2p.method = IcpMethod::point_to_point;
  p2p.max_iterations = 400;
  p2p.rotation_tolerance = 1e-12;
  p2p.translation_tolerance = 1e-12 * kSize;
  p2p.relative_rms_tolerance = 0.0;
  const IcpResult clean = align(finder, scan, Isometry3d::Identity(), p2p);
  EXPECT_LT(translation_error(clean.T_model_scan, true_pose()), 1e-7 * kSize);
  p2p.reject_boundary = false;
  const IcpResult biased = align(finder, scan, Isometry3d::Identity(), p2p);
  EXPECT_GT(translation_error(biased.T_model_scan, true_pose()), 1e-3 * kSize);
}

bool mentions(const DegeneracyReport& d, FreeDirection::Kind kind, const Vec3& direction) {
  for (const FreeDirection& f : d.free_directions) {
    if (f.kind == kind && std::abs(std::abs(f.direction.dot(direction)) - 1.0) < 1e-9) return true;
  }
  return false;
}

TEST(IcpDegeneracy, PlaneReportsTwoTranslationsAndTheNormalRotationAndStaysPut) {
  Rectangle patch;
  patch.half_u = patch.half_v = 0.5 * kSize;
  const Primitive patch_primitive = patch;
  PlaneFinder finder(Plane{Vec3::Zero(), Vec3::UnitZ()});
  const std::vector<Vec3> scan =
      to_scan(sample_uniform(std::span(&patch_primitive, 1), 2000, 15), true_pose());
  const IcpResult r = align(finder, scan, Isometry3d::Identity(), exact_options());
  ASSERT_EQ(r.termination, IcpTermination::degenerate) << r.brief_report();
  ASSERT_EQ(r.degeneracy.free_directions.size(), 3u) << r.degeneracy.describe();
  EXPECT_EQ(r.degeneracy.free_directions[0].description, "translation along (1, 0, 0)");
  EXPECT_EQ(r.degeneracy.free_directions[1].description, "translation along (0, 1, 0)");
  EXPECT_TRUE(mentions(r.degeneracy, FreeDirection::Kind::rotation, Vec3::UnitZ()))
      << r.degeneracy.describe();
  EXPECT_NE(r.brief_report().find("translation along (1, 0, 0)"), std::string::npos);
  EXPECT_LT(r.rms, 1e-9 * kSize);
  // No motion along the free directions. The constrained steps rotate about axes in the
  // plane and translate along its normal, so the result is the smallest rotation that lays
  // the scan plane onto z = 0, and the scan centroid keeps its (x, y).
  const Vec3 scan_normal = true_pose().linear().transpose() * Vec3::UnitZ();
  const Eigen::Matrix3d R_expected =
      Eigen::Quaterniond::FromTwoVectors(scan_normal, Vec3::UnitZ()).toRotationMatrix();
  EXPECT_LT((r.T_model_scan.linear() - R_expected).norm(), 1e-9);
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : scan)
    centroid += p;
  centroid /= static_cast<double>(scan.size());
  const Vec3 moved = r.T_model_scan * centroid;
  EXPECT_NEAR(moved.x(), centroid.x(), 1e-9 * kSize);
  EXPECT_NEAR(moved.y(), centroid.y(), 1e-9 * kSize);
  EXPECT_NEAR(moved.z(), 0.0, 1e-9 * kSize);
}

TEST(IcpDegeneracy, SphereReportsThreeRotationsAboutItsCentre) {
  const Sphere ball{Vec3(10, -5, 20), 30};
  SphereFinder finder(ball);
  // Antipodal pairs: the scan centroid is the sphere centre, so the minimal constrained
  // motion is the pure translation of the centre (rotations about it are free).
  const Primitive unit_sphere = Sphere{Vec3::Zero(), 1.0};
  std::vector<Vec3> model_points;
  for (const Vec3& u : sample_uniform(std::span(&unit_sphere, 1), 1000, 16)) {
    model_points.push_back(ball.center + ball.radius * u);
    model_points.push_back(ball.center - ball.radius * u);
  }
  const Isometry3d T_true = true_pose();
  const std::vector<Vec3> scan = to_scan(model_points, T_true);
  const IcpResult r = align(finder, scan, Isometry3d::Identity(), exact_options());
  ASSERT_EQ(r.termination, IcpTermination::degenerate) << r.brief_report();
  ASSERT_EQ(r.degeneracy.free_directions.size(), 3u) << r.degeneracy.describe();
  for (int axis = 0; axis < 3; ++axis) {
    const FreeDirection& f = r.degeneracy.free_directions[axis];
    EXPECT_EQ(f.kind, FreeDirection::Kind::rotation) << f.description;
    EXPECT_NEAR(std::abs(f.direction(axis)), 1.0, 1e-9) << f.description;
    // The axis passes through the centre.
    EXPECT_LT((f.point - ball.center).cross(f.direction).norm(), 1e-6 * kSize) << f.description;
  }
  EXPECT_EQ(r.degeneracy.free_directions[2].description,
            "rotation about axis (0, 0, 1) through (10, -5, 20)");
  // The scan's sphere centre lands on the model's, without any rotation.
  const Vec3 scan_center = T_true.inverse() * ball.center;
  EXPECT_LT((r.T_model_scan * scan_center - ball.center).norm(), 1e-9 * kSize);
  EXPECT_LT(rotation_angle(r.T_model_scan), 1e-9);
}

TEST(IcpDegeneracy, CylinderReportsItsAxisTranslationAndRotation) {
  const Vec3 axis = Vec3(0.0, 1.0, 1.0).normalized();
  const Cylinder tube{Vec3(5, 0, 0), axis, 20.0, 40.0};
  const Primitive tube_primitive = tube;
  UnionFinder finder({Cylinder{tube.origin, axis, tube.radius}});  // unbounded model
  const std::vector<Vec3> scan =
      to_scan(sample_uniform(std::span(&tube_primitive, 1), 2000, 17), true_pose());
  const IcpResult r = align(finder, scan, Isometry3d::Identity(), exact_options());
  ASSERT_EQ(r.termination, IcpTermination::degenerate) << r.brief_report();
  ASSERT_EQ(r.degeneracy.free_directions.size(), 2u) << r.degeneracy.describe();
  EXPECT_TRUE(mentions(r.degeneracy, FreeDirection::Kind::translation, axis));
  EXPECT_TRUE(mentions(r.degeneracy, FreeDirection::Kind::rotation, axis));
  const FreeDirection& rotation = r.degeneracy.free_directions[1];
  EXPECT_LT((rotation.point - tube.origin).cross(axis).norm(), 1e-6 * kSize);
  // Every scan point ends on the cylinder.
  EXPECT_LT(r.rms, 1e-9 * kSize);
}

TEST(IcpDeterminism, SameBitsForOneAndTwoThreadsAndSerial) {
  const std::vector<Primitive> primitives = scene();
  UnionFinder finder(primitives);
  // More points than a few reduction blocks so that the blocks really are split over threads.
  std::vector<Vec3> scan =
      to_scan(sample_uniform(primitives, 5 * kReductionBlock + 123, 18), true_pose());
  add_noise(scan, 1e-3 * kSize, 19);
  IcpOptions o = exact_options();
  o.kernel = RobustKernel::huber;
  o.max_iterations = 8;  // compare mid-run states too, not only a converged fixed point
  const auto run = [&](int threads, bool parallel) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    IcpOptions opt = o;
    opt.parallel = parallel;
    return align(finder, scan, Isometry3d::Identity(), opt);
  };
  const IcpResult one = run(1, true);
  const IcpResult two = run(2, true);
  const IcpResult serial = run(2, false);
  for (const IcpResult* other : {&two, &serial}) {
    EXPECT_TRUE(one.T_model_scan.matrix() == other->T_model_scan.matrix());
    EXPECT_TRUE(one.covariance == other->covariance);
    EXPECT_EQ(one.rms, other->rms);
    ASSERT_EQ(one.log.size(), other->log.size());
    for (std::size_t i = 0; i < one.log.size(); ++i)
      EXPECT_EQ(one.log[i].rms, other->log[i].rms);
  }
}

TEST(IcpCoarseToFine, ReachesTheSameAnswer) {
  const std::vector<Primitive> primitives = scene();
  UnionFinder finder(primitives);
  std::vector<Vec3> scan = to_scan(sample_uniform(primitives, 6000, 20), true_pose());
  add_noise(scan, 1e-3 * kSize, 21);
  // Both to the same fixed point to rounding: no statistical stop (which would leave each
  // within 0.1 standard deviations of it, by different amounts).
  IcpOptions o = exact_options();
  o.statistical_tolerance = 0.0;
  const IcpResult direct = align(finder, scan, Isometry3d::Identity(), o);
  o.coarse_sizes = {300, 1500};
  const IcpResult staged = align(finder, scan, Isometry3d::Identity(), o);
  ASSERT_EQ(staged.termination, IcpTermination::converged) << staged.brief_report();
  ASSERT_EQ(direct.termination, IcpTermination::converged) << direct.brief_report();
  EXPECT_LT(rotation_error(staged.T_model_scan, direct.T_model_scan), 1e-9);
  EXPECT_LT(translation_error(staged.T_model_scan, direct.T_model_scan), 1e-9 * kSize);
  // Three stages ran, on 300, 1500 and all points.
  ASSERT_FALSE(staged.log.empty());
  EXPECT_EQ(staged.log.front().points, 300u);
  EXPECT_EQ(staged.log.back().points, scan.size());
  EXPECT_EQ(staged.log.back().stage, 2);
  // The fine stage starts close: fewer full-size iterations than without coarse stages.
  int full_iterations = 0;
  for (const IcpIteration& it : staged.log)
    full_iterations += it.points == scan.size();
  EXPECT_LT(full_iterations, direct.iterations);
}

// Wraps a finder and checks the query contract the engine's warm start relies on: reset()
// once per alignment with the scan size, and scan_indices naming the scan point that each
// query point is (all query points are one rigid motion of the indexed scan points).
class CheckingFinder : public CorrespondenceFinder {
 public:
  CheckingFinder(CorrespondenceFinder& inner, std::span<const Vec3> scan)
      : inner_(inner), scan_(scan) {}
  void reset(std::size_t scan_size) override {
    ++resets;
    EXPECT_LE(scan_size, scan_.size());  // frames here are prefixes of scan_
    inner_.reset(scan_size);
  }
  void find(const CorrespondenceQuery& query, std::span<Correspondence> out) override {
    ++calls;
    EXPECT_EQ(query.points.size(), query.scan_indices.size());
    EXPECT_EQ(out.size(), query.points.size());
    sizes.push_back(query.points.size());
    // Rigid fit (Kabsch) from the indexed scan points to the query points: residual ~ 0.
    Vec3 mean_scan = Vec3::Zero(), mean_query = Vec3::Zero();
    for (std::size_t k = 0; k < query.points.size(); ++k) {
      EXPECT_LT(query.scan_indices[k], scan_.size());
      if (k > 0) {
        EXPECT_LT(query.scan_indices[k - 1], query.scan_indices[k]);
      }
      mean_scan += scan_[query.scan_indices[k]];
      mean_query += query.points[k];
    }
    mean_scan /= static_cast<double>(query.points.size());
    mean_query /= static_cast<double>(query.points.size());
    Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
    for (std::size_t k = 0; k < query.points.size(); ++k) {
      M += (query.points[k] - mean_query) * (scan_[query.scan_indices[k]] - mean_scan).transpose();
    }
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
    double worst = 0.0;
    for (std::size_t k = 0; k < query.points.size(); ++k) {
      const Vec3 fitted = mean_query + R * (scan_[query.scan_indices[k]] - mean_scan);
      worst = std::max(worst, (fitted - query.points[k]).norm());
    }
    EXPECT_LT(worst, 1e-9 * kSize);
    inner_.find(query, out);
  }
  int resets = 0;
  int calls = 0;
  std::vector<std::size_t> sizes;

 private:
  CorrespondenceFinder& inner_;
  std::span<const Vec3> scan_;
};

TEST(IcpFinderContract, StableScanIndicesAcrossStagesAndOneResetPerAlignment) {
  UnionFinder inner(scene());
  const std::vector<Vec3> scan = to_scan(sample_uniform(scene(), 3000, 25), true_pose());
  CheckingFinder finder(inner, scan);
  IcpOptions o = exact_options();
  o.coarse_sizes = {200};
  IcpSolver solver(o);
  const IcpResult first = solver.align(finder, scan, Isometry3d::Identity());
  ASSERT_EQ(first.termination, IcpTermination::converged) << first.brief_report();
  EXPECT_EQ(finder.resets, 1);
  // One call per iteration: the result's statistics reuse the last one (on all points).
  EXPECT_EQ(finder.calls, first.iterations);
  EXPECT_EQ(finder.sizes.front(), 200u);
  EXPECT_EQ(finder.sizes.back(), scan.size());
  // The solver reuses its buffers: a second, smaller frame and then the first one again
  // give exactly what fresh solvers give.
  const std::vector<Vec3> small(scan.begin(), scan.begin() + 700);
  const IcpResult second = solver.align(finder, small, Isometry3d::Identity());
  const IcpResult third = solver.align(finder, scan, Isometry3d::Identity());
  EXPECT_EQ(finder.resets, 3);
  EXPECT_TRUE(second.T_model_scan.matrix() ==
              align(inner, small, Isometry3d::Identity(), o).T_model_scan.matrix());
  EXPECT_TRUE(third.T_model_scan.matrix() == first.T_model_scan.matrix());
}

// IcpOptions::kernel_bounded_search: the passes on the way search only about twice Tukey's
// cut-off, so the outliers near the surfaces (the scene's uniform 10%, within the maximum
// distance) get no exact foot there; the first pass (no scale yet) and the last stage's later
// passes, whose answers are the result's, search to the maximum distance. The estimate is the
// same to a small fraction of its standard deviation, with the same inliers.
class BoundRecordingFinder : public CorrespondenceFinder {
 public:
  explicit BoundRecordingFinder(CorrespondenceFinder& inner) : inner_(inner) {}
  void reset(std::size_t scan_size) override { inner_.reset(scan_size); }
  void find(const CorrespondenceQuery& query, std::span<Correspondence> out) override {
    inner_.find(query, out);
    bounds.push_back(query.max_distance);
    sizes.push_back(query.points.size());
    answered.push_back(static_cast<std::size_t>(
        std::count_if(out.begin(), out.end(), [](const Correspondence& c) { return c.valid; })));
  }
  std::vector<double> bounds;
  std::vector<std::size_t> sizes, answered;

 private:
  CorrespondenceFinder& inner_;
};

TEST(IcpKernelBoundedSearch, OutliersGetNoFootOnTheWayAndTheResultIsTheSame) {
  const OutlierScene scene_10 = outlier_scene();
  UnionFinder inner(scene_10.primitives);
  const std::vector<Vec3>& scan = scene_10.scan;
  IcpOptions o = robust_options(RobustCase{"tukey", RobustKernel::tukey, 1.0});
  o.max_correspondence_distance = 0.5 * kSize;  // every outlier of the scene's box is within
  o.coarse_sizes = {800};
  o.robust_newton = true;
  BoundRecordingFinder full(inner);
  const IcpResult plain = IcpSolver(o).align(full, scan, Isometry3d::Identity());
  o.kernel_bounded_search = true;
  BoundRecordingFinder bounded(inner);
  const IcpResult fast = IcpSolver(o).align(bounded, scan, Isometry3d::Identity());
  ASSERT_EQ(plain.termination, IcpTermination::converged) << plain.brief_report();
  ASSERT_EQ(fast.termination, IcpTermination::converged) << fast.brief_report();
  // One query a pass: no pass had to be searched again.
  ASSERT_EQ(bounded.bounds.size(), fast.log.size());
  EXPECT_EQ(bounded.bounds.front(), o.max_correspondence_distance);
  int narrowed = 0;
  for (std::size_t k = 0; k < fast.log.size(); ++k) {
    const IcpIteration& it = fast.log[k];
    const bool result_pass =
        it.points == scan.size() && k > 0 && fast.log[k - 1].points == it.points;
    if (result_pass) {
      EXPECT_EQ(bounded.bounds[k], o.max_correspondence_distance) << "pass " << k;
    }
    if (bounded.bounds[k] < o.max_correspondence_distance) {
      ++narrowed;
      // No point that weighs was beyond the search: the cut-off stayed inside it.
      EXPECT_LT(4.685 * it.kernel_scale, bounded.bounds[k]) << "pass " << k;
      // ... and the far outliers were: fewer answers than points within the maximum distance.
      EXPECT_LT(bounded.answered[k], static_cast<std::size_t>(0.95 * double(bounded.sizes[k])));
    }
  }
  EXPECT_GE(narrowed, 2);
  EXPECT_EQ(bounded.bounds.back(), o.max_correspondence_distance);
  const Vec6 apart = pose_error(fast.T_model_scan, plain.T_model_scan);
  for (int j = 0; j < 6; ++j) {
    EXPECT_LT(std::abs(apart(j)), 0.05 * std::sqrt(scene_10.cov(j, j))) << "component " << j;
  }
  EXPECT_EQ(fast.inliers, plain.inliers);
  EXPECT_NEAR(fast.rms, plain.rms, 1e-3 * plain.rms);
  // Without the kernel's support (Huber weighs every point) the searches are never narrowed.
  o.kernel = RobustKernel::huber;
  BoundRecordingFinder huber(inner);
  IcpSolver(o).align(huber, scan, Isometry3d::Identity());
  for (const double bound : huber.bounds)
    EXPECT_EQ(bound, o.max_correspondence_distance);
}

// IcpOptions::initial_expected_motion is the first query's expected motion (a caller that
// knows its start to be close, e.g. the global stage's refined winner, lets the finder make
// certificates from the first pass); later queries carry the previous step's motion; the
// answers, and with them the pose, do not depend on it.
class MotionRecordingFinder : public CorrespondenceFinder {
 public:
  explicit MotionRecordingFinder(CorrespondenceFinder& inner) : inner_(inner) {}
  void reset(std::size_t scan_size) override { inner_.reset(scan_size); }
  void find(const CorrespondenceQuery& query, std::span<Correspondence> out) override {
    motions.push_back(query.expected_motion);
    inner_.find(query, out);
  }
  std::vector<double> motions;

 private:
  CorrespondenceFinder& inner_;
};

TEST(IcpFinderContract, TheFirstQueryExpectsTheInitialMotion) {
  UnionFinder inner(scene());
  const std::vector<Vec3> scan = to_scan(sample_uniform(scene(), 3000, 25), true_pose());
  IcpOptions o = exact_options();
  o.coarse_sizes = {200};
  MotionRecordingFinder unknown(inner);
  const IcpResult a = IcpSolver(o).align(unknown, scan, Isometry3d::Identity());
  o.initial_expected_motion = 1e-3 * kSize;
  MotionRecordingFinder known(inner);
  const IcpResult b = IcpSolver(o).align(known, scan, Isometry3d::Identity());
  ASSERT_EQ(a.termination, IcpTermination::converged) << a.brief_report();
  ASSERT_GE(known.motions.size(), 2u);
  EXPECT_TRUE(std::isinf(unknown.motions.front()));
  EXPECT_EQ(known.motions.front(), 1e-3 * kSize);
  EXPECT_EQ(std::vector<double>(known.motions.begin() + 1, known.motions.end()),
            std::vector<double>(unknown.motions.begin() + 1, unknown.motions.end()));
  EXPECT_TRUE(a.T_model_scan.matrix() == b.T_model_scan.matrix());
}

// CorrespondenceQuery::later_queries forecasts how many passes on all points follow a query,
// from the last stage's own contraction: 0 on the subsample stages and on the last stage's first
// two passes (no rate of its own yet); without a statistical tolerance (the absolute ones decide:
// many passes) what max_iterations leaves, at most 8; a forecast within the passes that followed
// give or take one. The answers, and with them the pose, do not
// depend on it.
class LaterRecordingFinder : public CorrespondenceFinder {
 public:
  explicit LaterRecordingFinder(CorrespondenceFinder& inner) : inner_(inner) {}
  void reset(std::size_t scan_size) override { inner_.reset(scan_size); }
  void find(const CorrespondenceQuery& query, std::span<Correspondence> out) override {
    sizes.push_back(query.points.size());
    later.push_back(query.later_queries);
    inner_.find(query, out);
  }
  std::vector<std::size_t> sizes;
  std::vector<int> later;

 private:
  CorrespondenceFinder& inner_;
};

TEST(IcpFinderContract, LaterQueriesForecastThePassesOnAllPoints) {
  UnionFinder inner(scene());
  std::vector<Vec3> scan = to_scan(sample_uniform(scene(), 20000, 31), true_pose());
  add_noise(scan, 1e-3 * kSize, 32);
  IcpOptions o = exact_options();
  o.coarse_sizes = {2000};
  o.statistical_tolerance = 0.0;
  o.rotation_tolerance = 0.0;
  o.relative_rms_tolerance = 0.0;
  o.max_iterations = 6;
  LaterRecordingFinder recording(inner);
  const IcpResult r = IcpSolver(o).align(recording, scan, Isometry3d::Identity());
  std::vector<int> full;  // the forecasts on all points, in order
  for (std::size_t k = 0; k < recording.sizes.size(); ++k) {
    if (recording.sizes[k] < scan.size()) {
      EXPECT_EQ(recording.later[k], 0) << k;
    } else {
      full.push_back(recording.later[k]);
    }
  }
  // No tolerance to meet: six passes on all points.
  ASSERT_EQ(full.size(), 6u) << r.brief_report();
  EXPECT_EQ(full, (std::vector<int>{0, 0, 3, 2, 1, 0}));

  // With the statistical tolerance the forecast stays within the passes that followed, give or
  // take one (a prediction), and the pose is the one without any forecast.
  IcpOptions statistical = exact_options();
  statistical.coarse_sizes = {2000};
  LaterRecordingFinder forecast(inner);
  const IcpResult a = IcpSolver(statistical).align(forecast, scan, Isometry3d::Identity());
  const IcpResult b = IcpSolver(statistical).align(inner, scan, Isometry3d::Identity());
  EXPECT_TRUE(a.T_model_scan.matrix() == b.T_model_scan.matrix());
  for (std::size_t k = 0; k < forecast.later.size(); ++k)
    EXPECT_LE(forecast.later[k], static_cast<int>(forecast.later.size() - k - 1) + 1) << k;
}

// The automatic levels are n/100 and n/10, each only with >= kAutoCoarseMinPoints points;
// explicit coarse_sizes win (those not below the scan size dropped); auto_coarse = false: none.
TEST(IcpCoarseToFine, ScheduleLevels) {
  using Sizes = std::vector<std::size_t>;
  const IcpOptions o;
  EXPECT_EQ(coarse_schedule(o, 1000000), (Sizes{10000, 100000}));
  EXPECT_EQ(coarse_schedule(o, 199999), (Sizes{19999}));
  EXPECT_EQ(coarse_schedule(o, 200000), (Sizes{2000, 20000}));
  EXPECT_EQ(coarse_schedule(o, 19999), Sizes{});
  IcpOptions explicit_sizes;
  explicit_sizes.coarse_sizes = {100, 5000};
  EXPECT_EQ(coarse_schedule(explicit_sizes, 3000), (Sizes{100}));
  IcpOptions off;
  off.auto_coarse = false;
  EXPECT_EQ(coarse_schedule(off, 1000000), Sizes{});
}

TEST(IcpOptionsValidation, ErrorsNameTheField) {
  const auto error_of = [](auto mutate) {
    IcpOptions o;
    mutate(o);
    return o.validate().value_or("");
  };
  EXPECT_FALSE(IcpOptions{}.validate());
  EXPECT_NE(error_of([](IcpOptions& o) { o.max_iterations = 0; }).find("max_iterations"),
            std::string::npos);
  EXPECT_NE(error_of([](IcpOptions& o) {
              o.max_correspondence_distance = -1;
            }).find("max_correspondence_distance"),
            std::string::npos);
  EXPECT_NE(error_of([](IcpOptions& o) { o.keep_fraction = 0.0; }).find("keep_fraction"),
            std::string::npos);
  EXPECT_NE(error_of([](IcpOptions& o) { o.kernel_scale = NAN; }).find("kernel_scale"),
            std::string::npos);
  EXPECT_NE(error_of([](IcpOptions& o) {
              o.coarse_sizes = {500, 100};
            }).find("coarse_sizes[1]"),
            std::string::npos);
  EXPECT_NE(error_of([](IcpOptions& o) { o.rotation_tolerance = -1; }).find("rotation_tolerance"),
            std::string::npos);
  EXPECT_NE(error_of([](IcpOptions& o) { o.min_correspondences = 2; }).find("min_correspondences"),
            std::string::npos);
  EXPECT_NE(
      error_of([](IcpOptions& o) { o.statistical_tolerance = -1; }).find("statistical_tolerance"),
      std::string::npos);
  EXPECT_NE(error_of([](IcpOptions& o) {
              o.coarse_statistical_tolerance = INFINITY;
            }).find("coarse_statistical_tolerance"),
            std::string::npos);
  EXPECT_NE(
      error_of([](IcpOptions& o) { o.degeneracy_threshold = 1.0; }).find("degeneracy_threshold"),
      std::string::npos);
  EXPECT_NE(error_of([](IcpOptions& o) {
              o.initial_expected_motion = 0.0;
            }).find("initial_expected_motion"),
            std::string::npos);
  // align() reports bad options and bad points as invalid_input, naming them.
  UnionFinder finder(scene());
  std::vector<Vec3> scan = sample_uniform(scene(), 100, 22);
  IcpOptions bad;
  bad.keep_fraction = 2.0;
  IcpResult r = align(finder, scan, Isometry3d::Identity(), bad);
  EXPECT_EQ(r.termination, IcpTermination::invalid_input);
  EXPECT_NE(r.message.find("keep_fraction"), std::string::npos) << r.message;
  scan[42].y() = NAN;
  r = align(finder, scan, Isometry3d::Identity(), IcpOptions{});
  EXPECT_EQ(r.termination, IcpTermination::invalid_input);
  EXPECT_NE(r.message.find("scan point 42"), std::string::npos) << r.message;
}

TEST(IcpTerminationCases, TooFewCorrespondencesAndIterationLimit) {
  UnionFinder finder(scene());
  const std::vector<Vec3> scan = to_scan(sample_uniform(scene(), 1000, 23), true_pose());
  IcpOptions o;
  o.max_correspondence_distance = 1e-6;  // nothing matches at the initial pose
  IcpResult r = align(finder, scan, Isometry3d::Identity(), o);
  EXPECT_EQ(r.termination, IcpTermination::too_few_correspondences) << r.brief_report();
  EXPECT_TRUE(r.T_model_scan.isApprox(Isometry3d::Identity()));
  // The message says why the points were rejected.
  EXPECT_NE(r.message.find("rejected: 1000 farther than max_correspondence_distance, 0 beyond "
                           "the model's free edges, 0 trimmed or weighted out"),
            std::string::npos)
      << r.message;
  o = IcpOptions{};
  o.max_iterations = 2;
  r = align(finder, scan, Isometry3d::Identity(), o);
  EXPECT_EQ(r.termination, IcpTermination::max_iterations) << r.brief_report();
  EXPECT_EQ(r.iterations, 2);
  const std::vector<Vec3> two_points(2, Vec3::Zero());
  r = align(finder, two_points, Isometry3d::Identity(), IcpOptions{});
  EXPECT_EQ(r.termination, IcpTermination::too_few_correspondences);
}

// inlier count and RMS of the distances at pose T, computed afresh (no rejection but the
// finder's boundary flag, as the solver with default options).
std::pair<std::size_t, double> statistics_at(CorrespondenceFinder& finder,
                                             const std::vector<Vec3>& scan, const Isometry3d& T) {
  std::vector<Vec3> moved;
  for (const Vec3& p : scan)
    moved.push_back(T * p);
  std::vector<Correspondence> out(scan.size());
  CorrespondenceQuery query;
  query.points = moved;
  finder.find(query, out);
  std::size_t inliers = 0;
  double sum = 0.0;
  for (const Correspondence& c : out) {
    if (!c.valid || c.on_boundary) continue;
    ++inliers;
    sum += c.distance * c.distance;
  }
  return {inliers, std::sqrt(sum / static_cast<double>(inliers))};
}

TEST(IcpStatistics, DescribeTheReturnedPose) {
  const std::vector<Primitive> primitives = scene();
  UnionFinder finder(primitives);
  std::vector<Vec3> scan = to_scan(sample_uniform(primitives, 4000, 31), true_pose());
  add_noise(scan, 1e-3 * kSize, 32);
  // Converged: the last iteration's step (computed at the returned pose) proves it and is not
  // applied, so rms and inliers are those of the returned pose, to the last bit.
  const IcpResult converged = align(finder, scan, Isometry3d::Identity(), exact_options());
  ASSERT_EQ(converged.termination, IcpTermination::converged) << converged.brief_report();
  EXPECT_TRUE(converged.statistics_at_pose);
  ASSERT_GE(converged.log.size(), 2u);
  EXPECT_FALSE(converged.log.back().applied);
  for (std::size_t k = 0; k + 1 < converged.log.size(); ++k)
    EXPECT_TRUE(converged.log[k].applied) << k;
  const auto [inliers, rms] = statistics_at(finder, scan, converged.T_model_scan);
  EXPECT_EQ(converged.inliers, inliers);
  EXPECT_EQ(converged.rms, rms);
  // Out of iterations: every step applied, and the returned pose evaluated once more.
  IcpOptions two = exact_options();
  two.max_iterations = 2;
  const IcpResult limited = align(finder, scan, Isometry3d::Identity(), two);
  ASSERT_EQ(limited.termination, IcpTermination::max_iterations) << limited.brief_report();
  EXPECT_TRUE(limited.statistics_at_pose);
  EXPECT_TRUE(limited.log.back().applied);
  const auto [limited_inliers, limited_rms] = statistics_at(finder, scan, limited.T_model_scan);
  EXPECT_EQ(limited.inliers, limited_inliers);
  EXPECT_EQ(limited.rms, limited_rms);
  EXPECT_GT(limited.rms, converged.rms);
  // A predicted final convergence keeps the statistics of the pose before its last step, and
  // says so.
  IcpOptions predicted = exact_options();
  predicted.predict_final_convergence = true;
  const IcpResult p = align(finder, scan, Isometry3d::Identity(), predicted);
  ASSERT_FALSE(p.log.empty());
  ASSERT_TRUE(p.log.back().predicted) << p.brief_report();
  EXPECT_TRUE(p.log.back().applied);
  EXPECT_FALSE(p.statistics_at_pose);
}

}  // namespace
}  // namespace nurbsreg::icp
