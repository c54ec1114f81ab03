// Knot insertion, clamping and Bézier decomposition must reproduce the entity exactly:
// max deviation at 10,000 random parameters < 1e-12 x bounding-box diagonal.
#include <gtest/gtest.h>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/decompose.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::random_curve;
using test::random_surface;
using test::uniform;

double diagonal_of(const std::vector<Vec3>& points) {
  Aabb box;
  for (const Vec3& p : points)
    box.extend(p);
  return box.diagonal();
}

// Evaluates the piece containing u (binary search on the pieces' parameter intervals).
Vec3 evaluate_pieces(const std::vector<BezierCurve>& pieces, double u) {
  auto it = std::upper_bound(pieces.begin(), pieces.end(), u,
                             [](double x, const BezierCurve& b) { return x < b.param.lo; });
  const BezierCurve& piece = it == pieces.begin() ? pieces.front() : *std::prev(it);
  return piece.evaluate(std::clamp(piece.param.to_local(u), 0.0, 1.0));
}

struct CurveCase {
  int degree;
  int count;
  bool rational;
  bool clamped;
};

class CurveDecomposition : public ::testing::TestWithParam<CurveCase> {};

TEST_P(CurveDecomposition, PiecesReproduceTheCurve) {
  const CurveCase c = GetParam();
  const NurbsCurve curve =
      random_curve(1000 + c.degree * 7 + c.count, c.degree, c.count, c.rational, c.clamped);
  ASSERT_FALSE(curve.validate()) << *curve.validate();
  const std::vector<BezierCurve> pieces = decompose(curve);
  const ParamInterval dom = curve.domain();
  EXPECT_DOUBLE_EQ(pieces.front().param.lo, dom.lo);
  EXPECT_DOUBLE_EQ(pieces.back().param.hi, dom.hi);
  for (std::size_t k = 1; k < pieces.size(); ++k) {
    EXPECT_EQ(pieces[k].param.lo, pieces[k - 1].param.hi);
  }
  const double tolerance = 1e-12 * diagonal_of(curve.control_points);
  std::mt19937_64 rng(42);
  double worst = 0.0;
  for (int s = 0; s < 10000; ++s) {
    const double u = uniform(rng, dom.lo, dom.hi);
    worst = std::max(worst, (evaluate_pieces(pieces, u) - curve.evaluate(u)).norm());
  }
  EXPECT_LT(worst, tolerance);
  // End points of the domain are exact control points of the first and last piece.
  EXPECT_LT((pieces.front().point(0) - curve.evaluate(dom.lo)).norm(), tolerance);
  EXPECT_LT((pieces.back().point(c.degree) - curve.evaluate(dom.hi)).norm(), tolerance);
}

INSTANTIATE_TEST_SUITE_P(
    Degrees, CurveDecomposition,
    ::testing::Values(CurveCase{1, 6, false, true}, CurveCase{2, 9, true, true},
                      CurveCase{3, 12, false, true}, CurveCase{3, 12, true, true},
                      CurveCase{3, 10, false, false}, CurveCase{4, 11, true, false},
                      CurveCase{5, 20, true, true}, CurveCase{7, 15, false, false},
                      CurveCase{9, 25, true, true}, CurveCase{12, 30, true, false},
                      CurveCase{3, 1000, true, true}));

TEST(CurveDecomposition, ClampKeepsTheCurveOnItsDomain) {
  const NurbsCurve curve = random_curve(77, 3, 9, true, /*clamped=*/false);
  const NurbsCurve clamped = clamp(curve);
  ASSERT_FALSE(clamped.validate()) << *clamped.validate();
  for (int k = 0; k <= 3; ++k) {
    EXPECT_EQ(clamped.knots[k], clamped.knots.front());
    EXPECT_EQ(clamped.knots[clamped.knots.size() - 1 - k], clamped.knots.back());
  }
  std::mt19937_64 rng(5);
  const ParamInterval dom = curve.domain();
  for (int s = 0; s < 1000; ++s) {
    const double u = uniform(rng, dom.lo, dom.hi);
    EXPECT_LT((clamped.evaluate(u) - curve.evaluate(u)).norm(), 1e-13);
  }
}

TEST(CurveDecomposition, SplitReproducesBothHalves) {
  const std::vector<BezierCurve> pieces = decompose(random_curve(3, 5, 6, true));
  const BezierCurve& piece = pieces.front();
  BezierCurve left;
  BezierCurve right;
  piece.split(0.3, left, right);
  for (double t = 0.0; t <= 1.0; t += 0.01) {
    EXPECT_LT((left.evaluate(t) - piece.evaluate(0.3 * t)).norm(), 1e-14);
    EXPECT_LT((right.evaluate(t) - piece.evaluate(0.3 + 0.7 * t)).norm(), 1e-14);
  }
  EXPECT_DOUBLE_EQ(left.param.hi, piece.param.to_parent(0.3));
}

struct SurfaceCase {
  int degree_u, degree_v, count_u, count_v;
  bool rational;
  bool clamped;
};

class SurfaceDecomposition : public ::testing::TestWithParam<SurfaceCase> {};

TEST_P(SurfaceDecomposition, PatchesReproduceTheSurface) {
  const SurfaceCase c = GetParam();
  const NurbsSurface surface =
      random_surface(2000 + c.count_u * 31 + c.degree_v, c.degree_u, c.degree_v, c.count_u,
                     c.count_v, c.rational, c.clamped);
  ASSERT_FALSE(surface.validate()) << *surface.validate();
  int spans_u = 0;
  int spans_v = 0;
  const std::vector<BezierPatch> patches = decompose(surface, &spans_u, &spans_v);
  ASSERT_EQ(patches.size(), static_cast<std::size_t>(spans_u * spans_v));
  const double tolerance = 1e-12 * diagonal_of(surface.control_points);
  std::mt19937_64 rng(43);
  double worst = 0.0;
  for (int s = 0; s < 10000; ++s) {
    const BezierPatch& patch = patches[rng() % patches.size()];
    const double a = uniform(rng, 0, 1);
    const double b = uniform(rng, 0, 1);
    const Vec3 expected = surface.evaluate(patch.param_u.to_parent(a), patch.param_v.to_parent(b));
    worst = std::max(worst, (patch.evaluate(a, b) - expected).norm());
  }
  EXPECT_LT(worst, tolerance);
  // Splitting a patch reproduces it.
  BezierPatch low;
  BezierPatch high;
  patches.front().split_u(0.4, low, high);
  BezierPatch lh;
  BezierPatch hh;
  high.split_v(0.7, lh, hh);
  for (double s = 0.0; s <= 1.0; s += 0.1) {
    for (double t = 0.0; t <= 1.0; t += 0.1) {
      EXPECT_LT((hh.evaluate(s, t) - patches.front().evaluate(0.4 + 0.6 * s, 0.7 + 0.3 * t)).norm(),
                tolerance);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Degrees, SurfaceDecomposition,
    ::testing::Values(SurfaceCase{1, 1, 3, 4, false, true}, SurfaceCase{3, 3, 8, 8, false, true},
                      SurfaceCase{3, 3, 8, 7, true, true}, SurfaceCase{2, 5, 6, 9, true, false},
                      SurfaceCase{7, 7, 10, 9, true, true}, SurfaceCase{3, 8, 6, 14, false, true},
                      SurfaceCase{3, 3, 40, 40, true, true}));

}  // namespace
}  // namespace nurbsreg::engine
