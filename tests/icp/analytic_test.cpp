// Analytic closest points against brute force over dense samples of each primitive, the SE(3)
// exponential against Eigen's matrix exponential, and the degeneracy analysis against a
// helicoid, whose only free motion is a screw.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <unsupported/Eigen/MatrixFunctions>

#include "nurbsreg/icp/analytic.hpp"
#include "nurbsreg/icp/degeneracy.hpp"
#include "nurbsreg/icp/se3.hpp"

namespace nurbsreg::icp {
namespace {

using engine::Vec3;

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

// Dense samples of a bounded primitive with their covering radius h (every surface point is
// within h of a sample), by parameter grids.
struct Samples {
  std::vector<Vec3> points;
  double h = 0.0;
};

Samples dense_samples(const Primitive& primitive) {
  Samples s;
  constexpr int kGrid = 300;
  if (const auto* r = std::get_if<Rectangle>(&primitive)) {
    for (int i = 0; i <= kGrid; ++i) {
      for (int j = 0; j <= kGrid; ++j) {
        s.points.push_back(r->origin + (2.0 * i / kGrid - 1.0) * r->half_u * r->axis_u +
                           (2.0 * j / kGrid - 1.0) * r->half_v * r->axis_v);
      }
    }
    s.h = std::hypot(r->half_u, r->half_v) / kGrid;
  } else if (const auto* sp = std::get_if<Sphere>(&primitive)) {
    for (int i = 0; i <= kGrid; ++i) {
      const double theta = std::numbers::pi * i / kGrid;
      for (int j = 0; j < 2 * kGrid; ++j) {
        const double phi = std::numbers::pi * j / kGrid;
        s.points.push_back(sp->center + sp->radius * Vec3(std::sin(theta) * std::cos(phi),
                                                          std::sin(theta) * std::sin(phi),
                                                          std::cos(theta)));
      }
    }
    s.h = sp->radius * std::numbers::pi / kGrid;
  } else if (const auto* c = std::get_if<Cylinder>(&primitive)) {
    const Vec3 e1 = c->axis.unitOrthogonal();
    const Vec3 e2 = c->axis.cross(e1);
    for (int i = 0; i <= kGrid; ++i) {
      const double z = (2.0 * i / kGrid - 1.0) * c->half_length;
      for (int j = 0; j < 2 * kGrid; ++j) {
        const double phi = std::numbers::pi * j / kGrid;
        s.points.push_back(c->origin + z * c->axis +
                           c->radius * (std::cos(phi) * e1 + std::sin(phi) * e2));
      }
    }
    s.h = std::hypot(c->half_length / kGrid, c->radius * std::numbers::pi / (2 * kGrid));
  }
  return s;
}

TEST(ClosestPoint, MatchesBruteForceOnEveryPrimitive) {
  const std::vector<Primitive> primitives = {
      Rectangle{Vec3(1, 2, 3), Vec3(1, 1, 0).normalized(), Vec3(0, 0, 1), 4.0, 2.0},
      Sphere{Vec3(-1, 0.5, 2), 3.0},
      Cylinder{Vec3(0, 1, -1), Vec3(1, 2, 2).normalized(), 2.0, 3.0}};
  std::mt19937_64 rng(31);
  for (const Primitive& primitive : primitives) {
    ASSERT_FALSE(validate(primitive));
    const Samples samples = dense_samples(primitive);
    for (int trial = 0; trial < 40; ++trial) {
      const Vec3 p(uniform(rng, -8, 8), uniform(rng, -8, 8), uniform(rng, -8, 8));
      const Correspondence c = closest_point(primitive, p);
      ASSERT_TRUE(c.valid);
      EXPECT_NEAR(c.distance, (p - c.foot).norm(), 1e-12);
      EXPECT_NEAR(c.normal.norm(), 1.0, 1e-12);
      double brute = std::numeric_limits<double>::infinity();
      for (const Vec3& q : samples.points)
        brute = std::min(brute, (p - q).norm());
      // The exact foot is never farther than any surface sample, and at most h closer than
      // the nearest one.
      EXPECT_LE(c.distance, brute + 1e-12);
      EXPECT_GE(c.distance, brute - samples.h);
      // The foot lies on the primitive.
      const double foot_gap = closest_point(primitive, c.foot).distance;
      EXPECT_LT(foot_gap, 1e-12);
    }
  }
}

TEST(ClosestPoint, NormalsAndDegenerateQueries) {
  // Interior feet: p - foot is along the normal.
  const Sphere ball{Vec3(1, 1, 1), 2.0};
  const Correspondence outside = closest_point(ball, Vec3(4, 5, 1));
  EXPECT_LT((Vec3(4, 5, 1) - outside.foot).cross(outside.normal).norm(), 1e-12);
  EXPECT_NEAR(outside.distance, 3.0, 1e-12);
  // Centre of a sphere, axis of a cylinder: some foot at exactly radius distance.
  EXPECT_NEAR(closest_point(ball, ball.center).distance, 2.0, 1e-12);
  const Cylinder tube{Vec3::Zero(), Vec3::UnitZ(), 1.5};
  EXPECT_NEAR(closest_point(tube, Vec3(0, 0, 7)).distance, 1.5, 1e-12);
  // Infinite plane: signed offset along the normal.
  const Correspondence plane = closest_point(Plane{Vec3(0, 0, 2), Vec3::UnitZ()}, Vec3(5, 6, -1));
  EXPECT_NEAR(plane.distance, 3.0, 1e-12);
  EXPECT_LT((plane.foot - Vec3(5, 6, 2)).norm(), 1e-12);
}

TEST(ClosestPoint, ValidationNamesTheField) {
  EXPECT_NE(validate(Sphere{Vec3::Zero(), -1.0}).value_or("").find("sphere: radius"),
            std::string::npos);
  EXPECT_NE(validate(Plane{Vec3::Zero(), Vec3(0, 0, 2)}).value_or("").find("plane: normal"),
            std::string::npos);
  Rectangle skewed;
  skewed.axis_v = Vec3(1, 1, 0).normalized();
  EXPECT_NE(validate(skewed).value_or("").find("rectangle: axis_v"), std::string::npos);
  EXPECT_THROW(UnionFinder({Cylinder{Vec3::Zero(), Vec3::UnitZ(), 0.0}}), std::invalid_argument);
  const Primitive unbounded = Plane{};
  EXPECT_THROW(sample_uniform(std::span(&unbounded, 1), 10, 1), std::invalid_argument);
}

TEST(UnionFinder, ClosestOverAllPrimitivesSerialEqualsParallel) {
  const std::vector<Primitive> primitives = {Plane{Vec3::Zero(), Vec3::UnitZ()},
                                             Sphere{Vec3(0, 0, 5), 2.0},
                                             Cylinder{Vec3(4, 0, 0), Vec3::UnitY(), 1.0, 2.0}};
  UnionFinder finder(primitives);
  std::mt19937_64 rng(32);
  std::vector<Vec3> points(5000);
  std::vector<std::size_t> ids(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    points[i] = Vec3(uniform(rng, -6, 6), uniform(rng, -6, 6), uniform(rng, -3, 9));
    ids[i] = i;
  }
  std::vector<Correspondence> parallel(points.size()), serial(points.size());
  CorrespondenceQuery query{points, ids, 2.5, true};
  finder.find(query, parallel);
  query.parallel = false;
  finder.find(query, serial);
  for (std::size_t i = 0; i < points.size(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (const Primitive& p : primitives)
      best = std::min(best, closest_point(p, points[i]).distance);
    EXPECT_EQ(parallel[i].distance, best);
    EXPECT_EQ(parallel[i].valid, best <= 2.5);
    EXPECT_EQ(parallel[i].foot, serial[i].foot);
    EXPECT_EQ(parallel[i].valid, serial[i].valid);
  }
}

Eigen::Matrix4d hat(const Vec6& xi) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Zero();
  m.topLeftCorner<3, 3>() = skew(xi.head<3>());
  m.topRightCorner<3, 1>() = xi.tail<3>();
  return m;
}

TEST(Se3, ExponentialMatchesTheMatrixExponentialAndLogInvertsIt) {
  std::mt19937_64 rng(33);
  for (int trial = 0; trial < 200; ++trial) {
    Vec6 xi;
    for (int j = 0; j < 6; ++j)
      xi(j) = uniform(rng, -1, 1);
    // Angles from 1e-9 (series branch) to about 3 rad.
    const double angle = trial < 50 ? std::pow(10.0, -9 + trial * 0.1) : uniform(rng, 0.0, 3.0);
    xi.head<3>() *= angle / xi.head<3>().norm();
    const Eigen::Matrix4d reference = hat(xi).exp();
    EXPECT_LT((exp_se3(xi).matrix() - reference).norm(), 1e-12) << "angle " << angle;
    EXPECT_LT((log_se3(exp_se3(xi)) - xi).norm(), 1e-9) << "angle " << angle;
    EXPECT_LT((log_so3(exp_so3(xi.head<3>())) - xi.head<3>()).norm(), 1e-9);
    EXPECT_NEAR(rotation_angle(exp_se3(xi)), angle, 1e-12 + 1e-9 * angle);
  }
}

TEST(Degeneracy, HelicoidLeavesOneScrewWithItsPitch) {
  // Helicoid x(u, v) = (u cos v, u sin v, c v): invariant under rotation by t about z combined
  // with translation c t along z, a screw of pitch c. Build the scaled point-to-plane
  // Hessian from exact normals and check that this is the one free direction.
  const double pitch = 0.7;
  std::vector<Vec3> points, normals;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 60; ++j) {
      const double u = 0.5 + 2.0 * i / 39.0, v = -2.0 + 4.0 * j / 59.0;
      points.emplace_back(u * std::cos(v), u * std::sin(v), pitch * v);
      const Vec3 xu(std::cos(v), std::sin(v), 0.0);
      const Vec3 xv(-u * std::sin(v), u * std::cos(v), pitch);
      normals.push_back(xu.cross(xv).normalized());
    }
  }
  Vec3 c = Vec3::Zero();
  for (const Vec3& p : points)
    c += p;
  c /= static_cast<double>(points.size());
  double L = 0.0;
  for (const Vec3& p : points)
    L += (p - c).squaredNorm();
  L = std::sqrt(L / static_cast<double>(points.size()));
  Mat6 H = Mat6::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    Vec6 J;
    J << (points[i] - c).cross(normals[i]) / L, normals[i];
    H += J * J.transpose();
  }
  const DegeneracyReport report = analyse_degeneracy(H, c, L, 1e-6);
  ASSERT_EQ(report.free_directions.size(), 1u) << report.describe();
  const FreeDirection& f = report.free_directions[0];
  EXPECT_EQ(f.kind, FreeDirection::Kind::screw) << f.description;
  EXPECT_NEAR(std::abs(f.direction.z()), 1.0, 1e-9);
  EXPECT_NEAR(f.pitch * f.direction.z(), pitch, 1e-9);
  EXPECT_LT(f.point.head<2>().norm(), 1e-9);  // the axis is the z axis
  EXPECT_NE(f.description.find("screw about axis (0, 0, 1)"), std::string::npos) << f.description;
  EXPECT_GT(report.relative_eigenvalues(1), 1e-6);
}

}  // namespace
}  // namespace nurbsreg::icp
