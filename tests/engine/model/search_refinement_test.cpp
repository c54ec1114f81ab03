// Finer patches for the search where a surface's own are far from flat (model/search_refinement):
// which spans are cut and how, that the cut surface is the same function of (u, v) with the same
// face, and that a PreparedModel searching the pieces projects like a brute force of the surface.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "model/search_refinement.hpp"
#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "support/hard_surfaces.hpp"
#include "support/polygon_loop.hpp"
#include "support/random_entities.hpp"
#include "support/surface_reference.hpp"

namespace nurbsreg::engine {
namespace {

// A strip `length` long and `width` wide along x whose cross-section turns by `twist` radians
// from one end to the other (a ruled surface, degree (3, 1)): flat across, twisted along, like
// the IEA blade's 8 m by 5 cm patches.
NurbsSurface twisted_strip(double length, double width, double twist, int spans) {
  NurbsSurface s;
  s.name = "twisted strip";
  s.degree_u = 3;
  s.degree_v = 1;
  s.count_u = spans + 3;
  s.count_v = 2;
  s.knots_u = {0, 0, 0, 0};
  for (int k = 1; k < spans; ++k)
    s.knots_u.push_back(static_cast<double>(k) / spans);
  s.knots_u.insert(s.knots_u.end(), {1, 1, 1, 1});
  s.knots_v = {0, 0, 1, 1};
  for (int i = 0; i < s.count_u; ++i) {
    const double a = twist * i / (s.count_u - 1);
    for (int j = 0; j < 2; ++j) {
      const double y = (j - 0.5) * width;
      s.control_points.emplace_back(length * i / (s.count_u - 1), y * std::cos(a), y * std::sin(a));
    }
  }
  return s;
}

// The largest thickness ratio over the patches of a surface.
double thickest(const NurbsSurface& s) {
  double worst = 0.0;
  for (const BezierPatch& p : decompose(s))
    worst = std::max(worst, patch_thickness_ratio(p));
  return worst;
}

TEST(SearchRefinement, FlatPatchesAreKept) {
  // A plane with a wavy parametrisation (control points in z = 0): every ratio is 0.
  NurbsSurface s = test::random_surface(4401, 3, 3, 7, 6, false);
  for (Vec3& c : s.control_points)
    c.z() = 0.0;
  EXPECT_EQ(thickest(s), 0.0);
  const SpanPieces pieces = search_pieces(s);
  for (int k : pieces.u)
    EXPECT_EQ(k, 1);
  for (int k : pieces.v)
    EXPECT_EQ(k, 1);
  const NurbsSurface same = refine_for_search(s);
  EXPECT_EQ(same.knots_u, s.knots_u);
  EXPECT_EQ(same.knots_v, s.knots_v);
}

TEST(SearchRefinement, ATwistedStripIsCutAlongItsLengthOnly) {
  const NurbsSurface s = twisted_strip(100.0, 1.0, 3.0, 2);
  ASSERT_GT(thickest(s), kFlatEnough);
  const SpanPieces pieces = search_pieces(s);
  ASSERT_EQ(pieces.u.size(), 2u);
  ASSERT_EQ(pieces.v.size(), 1u);
  EXPECT_EQ(pieces.v[0], 1);  // cutting across a flat cross-section makes nothing thinner
  for (int k : pieces.u)
    EXPECT_GT(k, 1);
  // Each cut halves a piece's twist: the pieces end thin enough, or at the cap.
  const NurbsSurface cut = refine_for_search(s);
  for (int k : pieces.u)
    EXPECT_TRUE(k == kMaxPieces || thickest(cut) <= kFlatEnough) << k << " " << thickest(cut);
  EXPECT_LT(thickest(cut), 0.5 * thickest(s));
}

TEST(SearchRefinement, ACylinderQuarterIsCutAroundItsAxis) {
  // Degree (2, 1): u runs around the axis (a rational quarter circle), v along it.
  const NurbsSurface s = test::cylinder_strip(1.0, 3.0);
  const SpanPieces pieces = search_pieces(s);
  ASSERT_EQ(pieces.u.size(), 1u);
  EXPECT_GT(pieces.u[0], 1);
  EXPECT_EQ(pieces.v[0], 1);  // straight along the axis
  EXPECT_LE(thickest(refine_for_search(s)), kFlatEnough);
}

TEST(SearchRefinement, TheCutSurfaceIsTheSameFunctionWithTheSameFace) {
  for (const bool rational : {false, true}) {
    NurbsSurface s = test::random_surface(4402 + rational, 3, 2, 6, 5, rational);
    // Curl the sheet so that it is far from flat (its patches get cut).
    for (std::size_t k = 0; k < s.control_points.size(); ++k) {
      Vec3& c = s.control_points[k];
      c = Vec3(std::cos(3.0 * c.x()), std::sin(3.0 * c.x()), c.y());
    }
    s.trim_loops = {test::rectangle_loop(0.1, 0.8, 0.2, 0.9, 2, false)};
    s.reversed = true;
    const NurbsSurface cut = refine_for_search(s);
    ASSERT_GT(cut.knots_u.size() + cut.knots_v.size(), s.knots_u.size() + s.knots_v.size())
        << rational;
    EXPECT_EQ(cut.trim_loops.size(), 1u);
    EXPECT_TRUE(cut.reversed);
    EXPECT_EQ(cut.name, s.name);
    EXPECT_EQ(cut.domain_u().lo, s.domain_u().lo);
    EXPECT_EQ(cut.domain_v().hi, s.domain_v().hi);
    std::mt19937_64 rng(77);
    std::uniform_real_distribution<double> u(s.domain_u().lo, s.domain_u().hi);
    std::uniform_real_distribution<double> v(s.domain_v().lo, s.domain_v().hi);
    for (int k = 0; k < 500; ++k) {
      const double a = u(rng), b = v(rng);
      const SurfaceDerivatives d0 = s.derivatives(a, b), d1 = cut.derivatives(a, b);
      EXPECT_LT((d0.s - d1.s).norm(), 1e-12) << a << " " << b;
      EXPECT_LT((d0.su - d1.su).norm(), 1e-10 * (1.0 + d0.su.norm())) << a << " " << b;
      EXPECT_LT((d0.sv - d1.sv).norm(), 1e-10 * (1.0 + d0.sv.norm())) << a << " " << b;
    }
  }
}

TEST(SearchRefinement, APreparedModelSearchesThePiecesAndAnswersLikeTheSurface) {
  const NurbsSurface s = twisted_strip(20.0, 1.0, 4.0, 3);
  const PreparedModel model(test::model_of({s}));
  EXPECT_GT(model.patch_count(), decompose(s).size());
  // The model keeps the surface as given; (u, v) are its parameters.
  EXPECT_EQ(model.model().surfaces[0].knots_u, s.knots_u);
  const test::SurfaceReference reference(s, 400, 4000, 400);
  std::mt19937_64 rng(78);
  std::uniform_real_distribution<double> x(-1.0, 21.0), yz(-1.5, 1.5);
  std::vector<Vec3> points;
  for (int k = 0; k < 400; ++k)
    points.emplace_back(x(rng), yz(rng), yz(rng));
  Projector projector(model);
  ProjectionResults results;
  projector.project(PointView::of(points), {}, results);
  const double tolerance = 1e-9 * model.bounds().diagonal();
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_EQ(results.status[i], ProjectionStatus::ok);
    const test::ReferenceHit ref = reference.closest(points[i]);
    EXPECT_NEAR(results.distance[i], std::sqrt(ref.distance_sq), tolerance) << i;
    EXPECT_LT((s.evaluate(results.u[i], results.v[i]) - results.foot[i]).norm(), tolerance) << i;
  }
}

}  // namespace
}  // namespace nurbsreg::engine
