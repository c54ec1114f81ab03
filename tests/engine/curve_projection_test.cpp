// Point projection and inversion on NURBS curves (seed paper 002, circular clipping; seed 000,
// Ma & Hewitt) against the brute-force oracle in support/curve_reference.hpp.
// Criterion: no point whose distance exceeds the oracle's by more than 1e-9 x the bounding-box
// diagonal; |cos(tangent, p - foot)| < 1e-10 at interior foot points.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <random>

#include <nlohmann/json.hpp>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/curve_projection.hpp"
#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "support/curve_reference.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::reference_closest;
using test::reference_samples;
using test::ReferenceHit;
using test::uniform;

constexpr double kDistanceTolerance = 1e-9;  // x bounding-box diagonal
constexpr double kCosineTolerance = 1e-10;

double diagonal_of(const NurbsCurve& curve) {
  Aabb box;
  for (const Vec3& p : curve.control_points)
    box.extend(p);
  return box.diagonal();
}

NurbsCurve bezier(std::vector<Vec3> points, std::vector<double> weights = {}) {
  NurbsCurve c;
  c.name = "bezier";
  c.degree = static_cast<int>(points.size()) - 1;
  c.knots.assign(c.degree + 1, 0.0);
  c.knots.insert(c.knots.end(), c.degree + 1, 1.0);
  c.dimension = 2;
  for (const Vec3& p : points) {
    if (p.z() != 0.0) c.dimension = 3;
  }
  c.control_points = std::move(points);
  c.weights = std::move(weights);
  return c;
}

// Seed 002, Fig. 5: the quartic Bézier on which Ma & Hewitt and Selimovic return wrong points.
NurbsCurve figure5_quartic() {
  return bezier({{-3.6164, -18.7790, 0},
                 {3.7808, 26.5070, 0},
                 {-0.6575, -45.9815, 0},
                 {-2.2353, 44.1267, 0},
                 {17.1765, -1.4683, 0}});
}

// Fig. 5's test points: on the circle of radius 0.1340 about (0.5057, -2.4590).
std::vector<Vec3> figure5_points(int count) {
  std::vector<Vec3> points;
  for (int i = 0; i < count; ++i) {
    const double a = 2.0 * std::numbers::pi * i / count;
    points.emplace_back(0.5057 + 0.1340 * std::cos(a), -2.4590 + 0.1340 * std::sin(a), 0.0);
  }
  return points;
}

// Points around the curve: C(u) plus an offset of random direction and length up to
// `spread` x diagonal, plus a few far away.
std::vector<Vec3> points_near(const NurbsCurve& curve, int count, std::uint64_t seed,
                              double spread = 0.2) {
  std::mt19937_64 rng(seed);
  const ParamInterval dom = curve.domain();
  const double diag = diagonal_of(curve);
  std::vector<Vec3> points;
  for (int i = 0; i < count; ++i) {
    Vec3 dir(uniform(rng, -1, 1), uniform(rng, -1, 1),
             curve.dimension == 3 ? uniform(rng, -1, 1) : 0.0);
    if (dir.norm() < 1e-3) dir = Vec3(1, 0, 0);
    const double scale = i % 10 == 9 ? 3.0 : spread * uniform(rng, 0.001, 1.0);
    points.push_back(curve.evaluate(uniform(rng, dom.lo, dom.hi)) +
                     scale * diag * dir.normalized());
  }
  return points;
}

bool near_kink(const NurbsCurve& curve, double u) {
  const ParamInterval dom = curve.domain();
  const double eps = 1e-9 * dom.width();
  if (u - dom.lo <= eps || dom.hi - u <= eps) return true;  // an end, not an interior foot
  for (double k : curve.knots) {
    if (std::abs(k - u) <= eps &&
        std::count(curve.knots.begin(), curve.knots.end(), k) >= curve.degree) {
      return true;
    }
  }
  return false;
}

struct Accuracy {
  int points = 0;
  int worse = 0;         // distance exceeds the oracle's by more than the tolerance
  int inconsistent = 0;  // foot != C(u) or distance != |p - foot|
  int not_orthogonal = 0;
  double worst_excess = 0.0;  // max (distance - oracle) / diagonal
  double worst_cosine = 0.0;
};

// Projects every point with `strategy` and compares with the oracle.
Accuracy check_against_reference(const NurbsCurve& curve, const std::vector<Vec3>& points,
                                 CurveStrategy strategy, int samples_per_span = 64,
                                 bool check_orthogonality = true) {
  const CurveProjector projector(curve);
  const double diag = diagonal_of(curve);
  const std::vector<double> us = reference_samples(curve, samples_per_span);
  Accuracy acc;
  for (const Vec3& p : points) {
    const CurveHit hit = projector.project(p, strategy);
    const ReferenceHit ref = reference_closest(curve, p, us);
    const double distance = std::sqrt(hit.distance_sq);
    ++acc.points;
    const double excess = (distance - ref.distance) / diag;
    acc.worst_excess = std::max(acc.worst_excess, excess);
    if (excess > kDistanceTolerance) ++acc.worse;
    if ((curve.evaluate(hit.u) - hit.foot).norm() > 1e-9 * diag ||
        std::abs((p - hit.foot).norm() - distance) > 1e-12 * diag) {
      ++acc.inconsistent;
    }
    if (check_orthogonality && distance > 1e-6 * diag && !near_kink(curve, hit.u)) {
      Vec3 d[2];
      curve.derivatives(hit.u, 1, d);
      const double cosine = std::abs(d[1].dot(p - hit.foot)) / (d[1].norm() * distance);
      acc.worst_cosine = std::max(acc.worst_cosine, cosine);
      if (cosine > kCosineTolerance) ++acc.not_orthogonal;
    }
  }
  return acc;
}

void expect_exact(const Accuracy& acc, const std::string& what) {
  EXPECT_EQ(acc.worse, 0) << what << ": worst excess " << acc.worst_excess << " x diagonal";
  EXPECT_EQ(acc.inconsistent, 0) << what;
  EXPECT_EQ(acc.not_orthogonal, 0) << what << ": worst |cos| " << acc.worst_cosine;
}

// ---------------------------------------------------------------------------------------------

TEST(CurveProjection, Figure5QuarticClippingIsExact) {
  const Accuracy acc = check_against_reference(figure5_quartic(), figure5_points(720),
                                               CurveStrategy::circular_clipping, 4096);
  expect_exact(acc, "Fig. 5 quartic");
}

TEST(CurveProjection, Figure5MaHewittForTheRecord) {
  // Seed 002 reports wrong Ma & Hewitt answers on Fig. 5; this implementation of Algorithms
  // 1/3/5 (flatness 1e-3 of the chord, Newton from the nearest candidate) happens to find the
  // closest point there, so the record is printed and the failures are shown on the cases of
  // MaHewittMissesTheClosestPoint instead. Both strategies must at least agree with the
  // oracle's distance to within the Newton tolerance on the points where MH is right.
  const NurbsCurve curve = figure5_quartic();
  const CurveProjector projector(curve);
  const std::vector<double> us = reference_samples(curve, 4096);
  int mh_wrong = 0;
  for (const Vec3& p : figure5_points(720)) {
    const ReferenceHit ref = reference_closest(curve, p, us);
    const double mh = std::sqrt(projector.project(p, CurveStrategy::ma_hewitt).distance_sq);
    if (mh > ref.distance + 1e-6) ++mh_wrong;
    EXPECT_GE(mh, ref.distance - 1e-9 * diagonal_of(curve));
  }
  std::cout << "Fig. 5: Ma & Hewitt wrong on " << mh_wrong << " of 720 points\n";
}

// Cases found by a seeded random search (control points rounded to 4 decimals) where Ma &
// Hewitt's Theorem 1 discards the sub-curve holding the closest point: a planar cubic and a
// twisted 3-D quartic (the 3-D failure Chen et al. 2007 point out; seeds 001/002 cite it).
struct Counterexample {
  NurbsCurve curve;
  Vec3 point;
};

std::vector<Counterexample> ma_hewitt_counterexamples() {
  return {
      {bezier({{0.8333, -0.8134, 0},
               {-0.2764, 0.0943, 0},
               {0.2514, -0.3010, 0},
               {0.7969, -0.9001, 0}}),
       Vec3(0.4177, -0.4825, 0)},
      {bezier({{-0.3012, 0.8882, 0.1354},
               {-0.5248, 0.5479, 0.1540},
               {-0.2103, -0.8252, -0.6704},
               {0.9552, -0.2149, 0.2314},
               {0.2483, -0.3202, 0.0276}}),
       Vec3(0.6628, -1.2371, -1.0740)},
  };
}

TEST(CurveProjection, MaHewittMissesTheClosestPoint) {
  for (const Counterexample& c : ma_hewitt_counterexamples()) {
    const CurveProjector projector(c.curve);
    const ReferenceHit ref = reference_closest(c.curve, c.point, 4096);
    const double mh = std::sqrt(projector.project(c.point, CurveStrategy::ma_hewitt).distance_sq);
    const double cc = std::sqrt(projector.project(c.point).distance_sq);
    // A property of the method: measurably farther than the true closest point.
    EXPECT_GT(mh, ref.distance * (1.0 + 1e-3)) << "dimension " << c.curve.dimension;
    EXPECT_LE(cc, ref.distance + kDistanceTolerance * diagonal_of(c.curve));
    std::cout << "Ma & Hewitt " << mh << " vs closest " << ref.distance << " (clipping " << cc
              << ")\n";
  }
}

struct RandomCase {
  int degree;
  int count;
  bool rational;
  bool clamped;
  int dimension;
  int points;
};

class RandomCurveProjection : public ::testing::TestWithParam<RandomCase> {};

TEST_P(RandomCurveProjection, MatchesTheOracle) {
  const RandomCase c = GetParam();
  const NurbsCurve curve = test::random_curve(5000 + 13 * c.degree + c.count, c.degree, c.count,
                                              c.rational, c.clamped, c.dimension);
  ASSERT_FALSE(curve.validate()) << *curve.validate();
  const int samples = c.count > 100 ? 24 : 64;
  const Accuracy acc = check_against_reference(curve, points_near(curve, c.points, 99 + c.count),
                                               CurveStrategy::circular_clipping, samples);
  expect_exact(acc, "random curve");
}

INSTANTIATE_TEST_SUITE_P(
    DegreesAndKnots, RandomCurveProjection,
    ::testing::Values(RandomCase{1, 8, false, true, 3, 200}, RandomCase{2, 9, true, true, 2, 200},
                      RandomCase{3, 12, false, true, 3, 200}, RandomCase{3, 12, true, true, 2, 200},
                      RandomCase{4, 11, true, false, 3, 200}, RandomCase{5, 14, true, true, 3, 200},
                      RandomCase{6, 10, false, false, 2, 200},
                      RandomCase{7, 15, true, true, 3, 200}, RandomCase{8, 12, true, false, 3, 200},
                      RandomCase{9, 20, true, true, 3, 200},
                      RandomCase{3, 1000, true, true, 3, 40}));

}  // namespace
}  // namespace nurbsreg::engine
