// Faces that are a rectangle of their surface's domain (trim/rectangle_face.hpp): which loops
// are one, and restrict_domain, the surface cut to such a rectangle, against the surface itself.
// Their projection against a brute force of the trimmed face is in trimmed_projection_test.cpp.

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/prepared_model.hpp"
#include "support/polygon_loop.hpp"
#include "support/random_entities.hpp"
#include "trim/rectangle_face.hpp"

namespace nurbsreg::engine {
namespace {

using test::polygon_loop;
using test::rectangle_loop;
using test::uv_line;

NurbsSurface unit_sheet() {
  NurbsSurface s = test::random_surface(8101, 3, 2, 7, 6, false);
  s.knots_u = {0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1};
  s.knots_v = {0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1};
  return s;
}

TEST(RectangleFace, AnIsoParametricRectangleLoopIsOneClippedToTheDomain) {
  NurbsSurface s = unit_sheet();
  for (const bool reverse : {false, true}) {
    for (const int pieces : {1, 3}) {
      s.trim_loops = {rectangle_loop(0.2, 0.7, 0.5, 1.0, pieces, reverse)};
      const std::optional<UvRectangle> r = rectangle_of_face(s);
      ASSERT_TRUE(r.has_value()) << reverse << " " << pieces;
      EXPECT_EQ(r->u.lo, 0.2);
      EXPECT_EQ(r->u.hi, 0.7);
      EXPECT_EQ(r->v.lo, 0.5);
      EXPECT_EQ(r->v.hi, 1.0);
    }
  }
  // The domain's own border, and a loop beyond it (clipped: the face is the whole domain).
  s.trim_loops = {rectangle_loop(0.0, 1.0, 0.0, 1.0)};
  ASSERT_TRUE(rectangle_of_face(s).has_value());
  s.trim_loops = {rectangle_loop(-0.1, 1.0, 0.0, 1.2)};
  const std::optional<UvRectangle> clipped = rectangle_of_face(s);
  ASSERT_TRUE(clipped.has_value());
  EXPECT_EQ(clipped->u.lo, 0.0);
  EXPECT_EQ(clipped->v.hi, 1.0);
  // A side's u off by a last bit (a conversion's rounding) is still on the line.
  TrimLoop nudged = rectangle_loop(0.2, 0.7, 0.5, 1.0);
  nudged.curves[1].uv.control_points[1].x() = std::nextafter(0.7, 1.0);
  s.trim_loops = {nudged};
  EXPECT_TRUE(rectangle_of_face(s).has_value());
}

TEST(RectangleFace, OtherLoopsAreNot) {
  NurbsSurface s = unit_sheet();
  const auto is_one = [&s](std::vector<TrimLoop> loops) {
    s.trim_loops = std::move(loops);
    return rectangle_of_face(s).has_value();
  };
  EXPECT_FALSE(is_one({}));  // untrimmed: nothing to convert
  // Two loops (a rectangle with a hole).
  EXPECT_FALSE(is_one({rectangle_loop(0.1, 0.9, 0.1, 0.9), rectangle_loop(0.4, 0.6, 0.4, 0.6)}));
  // A triangle; a rectangle with one corner cut; a side bowed inwards (a quadratic whose middle
  // control point is off the line).
  EXPECT_FALSE(is_one({polygon_loop({{0.1, 0.1}, {0.9, 0.1}, {0.9, 0.9}})}));
  EXPECT_FALSE(
      is_one({polygon_loop({{0.1, 0.1}, {0.9, 0.1}, {0.9, 0.8}, {0.8, 0.9}, {0.1, 0.9}})}));
  TrimLoop bowed = rectangle_loop(0.1, 0.9, 0.1, 0.9);
  NurbsCurve side;
  side.degree = 2;
  side.dimension = 2;
  side.knots = {0, 0, 0, 1, 1, 1};
  side.control_points = {Vec3(0.1, 0.1, 0), Vec3(0.5, 0.3, 0), Vec3(0.9, 0.1, 0)};
  bowed.curves[0].uv = side;
  EXPECT_FALSE(is_one({bowed}));
  // A side off its line by more than the allowance.
  TrimLoop tilted = rectangle_loop(0.1, 0.9, 0.1, 0.9);
  tilted.curves[1].uv.control_points[1].x() = 0.9 + 1e-9;
  EXPECT_FALSE(is_one({tilted}));
  // A loop along the border that does not go around it: out along the bottom and up the right
  // side, then back the same way (no area).
  EXPECT_FALSE(is_one({polygon_loop({{0.1, 0.1}, {0.9, 0.1}, {0.9, 0.9}, {0.9, 0.1}})}));
  // Around twice.
  TrimLoop twice = rectangle_loop(0.1, 0.9, 0.1, 0.9);
  const TrimLoop again = twice;
  twice.curves.insert(twice.curves.end(), again.curves.begin(), again.curves.end());
  EXPECT_FALSE(is_one({twice}));
  // Curves on the border with a gap that cuts a corner (the engine closes gaps with straight
  // segments: the face would miss that corner).
  TrimLoop gap = rectangle_loop(0.1, 0.9, 0.1, 0.9);
  gap.curves[0].uv = uv_line({0.1, 0.1}, {0.85, 0.1});
  gap.curves[1].uv = uv_line({0.9, 0.15}, {0.9, 0.9});
  EXPECT_FALSE(is_one({gap}));
  // A rectangle wholly outside the domain.
  EXPECT_FALSE(is_one({rectangle_loop(1.5, 2.0, 0.2, 0.4)}));
}

// restrict_domain is the same function of (u, v) on the rectangle, with the rectangle as its
// domain: at rectangle ends inside knot spans and on knots, polynomial and rational.
TEST(RectangleFace, RestrictDomainIsTheSameSurfaceOnTheRectangle) {
  std::mt19937_64 rng(8102);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (const bool rational : {false, true}) {
    for (int trial = 0; trial < 6; ++trial) {
      NurbsSurface s =
          test::random_surface(8200 + trial, 1 + trial % 3, 2 + trial % 2, 7, 8, rational,
                               trial != 5);  // trial 5: unclamped knot vectors
      s.reversed = trial % 2 == 1;
      const ParamInterval du = s.domain_u(), dv = s.domain_v();
      // Trial 0: the whole domain; 1: ends on interior knots; others: anywhere.
      ParamInterval u = du, v = dv;
      if (trial == 1) {
        u = {s.knots_u[static_cast<std::size_t>(s.degree_u) + 1], du.hi};
        v = {dv.lo, s.knots_v[s.knots_v.size() - static_cast<std::size_t>(s.degree_v) - 2]};
      } else if (trial > 1) {
        const double a = unit(rng), b = unit(rng), c = unit(rng), d = unit(rng);
        u = {du.to_parent(0.5 * std::min(a, b)), du.to_parent(0.5 + 0.5 * std::max(a, b))};
        v = {dv.to_parent(0.5 * std::min(c, d)), dv.to_parent(0.5 + 0.5 * std::max(c, d))};
      }
      const NurbsSurface r = restrict_domain(s, u, v);
      ASSERT_FALSE(r.validate().has_value()) << *r.validate();
      EXPECT_EQ(r.domain_u().lo, u.lo);
      EXPECT_EQ(r.domain_u().hi, u.hi);
      EXPECT_EQ(r.domain_v().lo, v.lo);
      EXPECT_EQ(r.domain_v().hi, v.hi);
      EXPECT_EQ(r.reversed, s.reversed);
      EXPECT_EQ(r.is_rational(), s.is_rational());
      EXPECT_FALSE(r.is_trimmed());
      for (int i = 0; i <= 8; ++i) {
        for (int j = 0; j <= 8; ++j) {
          const double a = u.to_parent(i / 8.0), b = v.to_parent(j / 8.0);
          const SurfaceDerivatives x = s.derivatives(a, b), y = r.derivatives(a, b);
          EXPECT_LE((x.s - y.s).norm(), 1e-12 * (1.0 + x.s.norm())) << rational << trial;
          // Derivatives inside: on the rectangle's sides, which may be knots of the surface's
          // (random) knot vectors of any multiplicity, it may be C0 and the two sides differ.
          if (i == 0 || i == 8 || j == 0 || j == 8) continue;
          EXPECT_LE((x.su - y.su).norm(), 1e-10 * (1.0 + x.su.norm())) << rational << trial;
          EXPECT_LE((x.sv - y.sv).norm(), 1e-10 * (1.0 + x.sv.norm())) << rational << trial;
        }
      }
    }
  }
}

// PreparedModel projects a rectangle face as its rectangle: no region, no edge pieces, only the
// rectangle's patches in the hierarchy; the other faces are left alone.
TEST(RectangleFace, PreparedModelMakesTheRectangleAnUntrimmedSurface) {
  Model m;
  NurbsSurface half = unit_sheet();
  half.trim_loops = {rectangle_loop(0.0, 1.0, 0.5, 1.0, 2, true)};
  NurbsSurface holed = unit_sheet();
  holed.trim_loops = {rectangle_loop(0.0, 1.0, 0.0, 1.0), rectangle_loop(0.4, 0.6, 0.4, 0.6)};
  m.surfaces = {half, holed};
  const PreparedModel prepared(m);
  EXPECT_TRUE(prepared.rectangle_face(0));
  EXPECT_FALSE(prepared.rectangle_face(1));
  EXPECT_EQ(prepared.surface_region(0), nullptr);
  EXPECT_NE(prepared.surface_region(1), nullptr);
  EXPECT_FALSE(prepared.model().surfaces[0].is_trimmed());
  EXPECT_EQ(prepared.surface_domain(0).v.lo, 0.5);
  // The half's patches: the 2 upper of 4 spans in v (cut finer where they are far from flat,
  // model/search_refinement.hpp), which cover the rectangle and nothing else.
  double half_area = 0.0;
  for (std::size_t i = 0; i < prepared.patch_count(); ++i) {
    if (prepared.patch_surface(i) != 0) continue;
    const BezierPatch& bp = prepared.patch(i).patch;
    EXPECT_GE(bp.param_v.lo, 0.5);
    half_area += (bp.param_u.hi - bp.param_u.lo) * (bp.param_v.hi - bp.param_v.lo);
  }
  EXPECT_NEAR(half_area, 0.5, 1e-15);
  for (std::size_t e = 0; e < prepared.edge_piece_count(); ++e)
    EXPECT_EQ(prepared.edge_piece_info(e).surface, 1);
}

}  // namespace
}  // namespace nurbsreg::engine
