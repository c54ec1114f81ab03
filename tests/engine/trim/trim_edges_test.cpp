// trim_edges(): the exact 3-D image of degree-1 uv curves must match S(uv(t)) evaluated
// directly (NurbsSurface::evaluate after NurbsCurve::evaluate) to 1e-12 x the surface's
// bounding diagonal, on polynomial and strongly rational surfaces, for lines that cross many
// knot lines, pass exactly through knot intersections, or run along knot lines.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/trim_region.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::uniform;

NurbsCurve uv_polyline(const std::vector<Vec2>& points, const std::vector<double>& weights = {},
                       double t0 = 0.0, double t1 = 1.0) {
  NurbsCurve c;
  c.degree = 1;
  c.dimension = 2;
  const int n = static_cast<int>(points.size());
  c.knots = {t0, t0};
  for (int k = 1; k < n - 1; ++k)
    c.knots.push_back(t0 + (t1 - t0) * k / (n - 1));
  c.knots.insert(c.knots.end(), {t1, t1});
  for (const Vec2& p : points)
    c.control_points.emplace_back(p.x(), p.y(), 0.0);
  c.weights = weights;
  return c;
}

// Random surface with weights spread over 0.01 .. 100 when rational; `uniform_knots` makes
// the interior knots k / (count - degree) so that diagonals pass through knot intersections.
NurbsSurface surface(std::uint64_t seed, int pu, int pv, int nu, int nv, bool rational,
                     bool uniform_knots) {
  NurbsSurface s = test::random_surface(seed, pu, pv, nu, nv, false);
  std::mt19937_64 rng(seed * 3 + 1);
  if (rational) {
    s.weights.clear();
    for (int k = 0; k < nu * nv; ++k)
      s.weights.push_back(std::exp(uniform(rng, std::log(0.01), std::log(100.0))));
  }
  if (uniform_knots) {
    for (auto [knots, p, n] : {std::tuple{&s.knots_u, pu, nu}, std::tuple{&s.knots_v, pv, nv}}) {
      knots->assign(p + 1, 0.0);
      for (int k = 1; k < n - p; ++k)
        knots->push_back(static_cast<double>(k) / (n - p));
      knots->insert(knots->end(), p + 1, 1.0);
    }
  }
  return s;
}

double diagonal(const NurbsSurface& s) {
  Aabb box;
  for (const Vec3& p : s.control_points)
    box.extend(p);
  return box.diagonal();
}

// Max |edge(t) - S(uv(t))| over many t (all knots of the uv curve and of the edge included).
double worst_deviation(const NurbsSurface& s, const NurbsCurve& uv, const NurbsCurve& edge) {
  std::vector<double> ts;
  const ParamInterval d = uv.domain();
  for (int k = 0; k <= 3000; ++k)
    ts.push_back(d.lo + d.width() * k / 3000.0);
  for (double k : edge.knots)
    ts.push_back(std::clamp(k, d.lo, d.hi));
  double worst = 0.0;
  for (double t : ts) {
    const Vec3 p = uv.evaluate(t);
    worst = std::max(worst, (edge.evaluate(t) - s.evaluate(p.x(), p.y())).norm());
  }
  return worst;
}

// Worst deviation / diagonal seen by expect_exact since the last report.
double worst_ratio = 0.0;

void report(const char* test) {
  std::printf("%s: worst |edge(t) - S(uv(t))| / diagonal = %.3g\n", test, worst_ratio);
  worst_ratio = 0.0;
}

void expect_exact(const NurbsSurface& s, const NurbsCurve& uv, const char* what) {
  NurbsSurface trimmed = s;
  trimmed.trim_loops = {TrimLoop{{TrimCurve{uv, std::nullopt}}}};
  const std::vector<TrimEdge> edges = trim_edges(trimmed);
  ASSERT_EQ(edges.size(), 1u);
  const NurbsCurve& e = edges[0].edge;
  ASSERT_FALSE(e.validate()) << *e.validate();
  EXPECT_EQ(e.dimension, 3);
  EXPECT_EQ(e.domain().lo, uv.domain().lo);
  EXPECT_EQ(e.domain().hi, uv.domain().hi);
  for (double w : e.weights)
    EXPECT_GT(w, 0.0);
  const double dev = worst_deviation(s, uv, e);
  worst_ratio = std::max(worst_ratio, dev / diagonal(s));
  EXPECT_LE(dev, 1e-12 * diagonal(s))
      << what << ": degree " << e.degree << ", " << e.count() << " control points";
}

struct Case {
  int pu, pv, nu, nv;
  bool rational;
};

class TrimEdgeImage : public ::testing::TestWithParam<Case> {};

TEST_P(TrimEdgeImage, RandomLinesCrossingManyKnotLines) {
  const Case c = GetParam();
  for (int uniform_knots = 0; uniform_knots <= 1; ++uniform_knots) {
    const NurbsSurface s =
        surface(100 + c.pu * 13 + c.pv, c.pu, c.pv, c.nu, c.nv, c.rational, uniform_knots);
    ASSERT_FALSE(s.validate()) << *s.validate();
    std::mt19937_64 rng(5);
    for (int k = 0; k < 6; ++k) {
      std::vector<Vec2> pts;
      std::vector<double> w;
      for (int i = 0; i < 2 + k % 3; ++i) {
        pts.emplace_back(uniform(rng, 0, 1), uniform(rng, 0, 1));
        w.push_back(std::exp(uniform(rng, -2, 2)));
      }
      // Rational uv curves too (a rational line piece is the same segment, reparameterised).
      expect_exact(s, uv_polyline(pts, k % 2 ? w : std::vector<double>{}, -1.5, 2.0),
                   "random polyline");
    }
  }
  report("random lines");
}

TEST_P(TrimEdgeImage, LinesThroughKnotIntersectionsAndAlongKnotLines) {
  const Case c = GetParam();
  const NurbsSurface s = surface(200 + c.pu * 13 + c.pv, c.pu, c.pv, c.nu, c.nv, c.rational, true);
  const double ku = 1.0 / (c.nu - c.pu), kv = 1.0 / (c.nv - c.pv);
  // The domain diagonal passes through every knot intersection (k/n, k/n) when n_u == n_v.
  expect_exact(s, uv_polyline({{0, 0}, {1, 1}}), "diagonal");
  expect_exact(s, uv_polyline({{0, 1}, {1, 0}}), "anti-diagonal");
  // From one knot intersection to another, through further ones.
  expect_exact(s, uv_polyline({{ku, kv}, {1 - ku, 1 - kv}, {1 - ku, kv}, {ku, kv}}),
               "knot intersections");
  // Along knot lines (iso lines: lower degree) and along the domain boundary.
  expect_exact(s, uv_polyline({{ku, 0}, {ku, 1}, {1, 1}, {0, 1}, {0, 2 * kv}, {1, 2 * kv}}),
               "along knot lines");
  // Rational uv along a knot line (w varies: not an iso line in t).
  expect_exact(s, uv_polyline({{ku, 0}, {ku, 1}}, {0.2, 5.0}), "rational iso line");
  report("knot intersections");
}

INSTANTIATE_TEST_SUITE_P(Surfaces, TrimEdgeImage,
                         ::testing::Values(Case{1, 1, 5, 5, false}, Case{2, 2, 7, 7, true},
                                           Case{3, 3, 9, 9, false}, Case{3, 3, 9, 9, true},
                                           Case{2, 5, 8, 9, true}, Case{6, 6, 9, 9, true},
                                           Case{2, 3, 30, 25, true}));

// Unclamped knot vectors (domain [knots[p], knots[n]]), and lines leaving the domain (where S
// clamps its parameters: the edge must follow).
TEST(TrimEdges, UnclampedSurfaceAndLinesLeavingTheDomain) {
  for (bool rational : {false, true}) {
    NurbsSurface s = test::random_surface(rational ? 31 : 32, 3, 2, 8, 7, rational, false);
    ASSERT_FALSE(s.validate()) << *s.validate();
    const ParamInterval du = s.domain_u(), dv = s.domain_v();
    std::mt19937_64 rng(13);
    for (int k = 0; k < 5; ++k) {
      std::vector<Vec2> pts;
      for (int i = 0; i < 3; ++i)
        pts.emplace_back(uniform(rng, du.lo, du.hi), uniform(rng, dv.lo, dv.hi));
      expect_exact(s, uv_polyline(pts), "unclamped");
    }
    expect_exact(
        s,
        uv_polyline(
            {{du.lo - 0.3, dv.lo + 0.1}, {du.hi + 0.2, dv.hi - 0.1}, {du.hi + 0.4, dv.hi + 0.3}}),
        "leaving the domain");
  }
  report("unclamped");
}

TEST(TrimEdges, GivenEdgesPassThroughAndTooHighDegreeThrows) {
  NurbsSurface s = surface(7, 7, 6, 9, 9, true, true);
  NurbsCurve given = test::random_curve(3, 3, 6, true);
  given.knots = {0, 0, 0, 0, 0.3, 0.6, 1, 1, 1, 1};
  NurbsCurve uv_given = uv_polyline({{0.1, 0.1}, {0.9, 0.1}, {0.5, 0.9}});
  uv_given.degree = 2;
  uv_given.knots = {0, 0, 0, 1, 1, 1};
  s.trim_loops = {TrimLoop{{TrimCurve{uv_given, given},
                            TrimCurve{uv_polyline({{0.5, 0.9}, {0.5, 0.1}}), std::nullopt}}}};
  // Degree 7 + 6 = 13 > kMaxDegree on the oblique... here the second curve is an iso line in u
  // (degree 6 only), so it maps.
  std::vector<TrimEdge> edges = trim_edges(s);
  ASSERT_EQ(edges.size(), 2u);
  EXPECT_EQ(edges[0].loop, 0);
  EXPECT_EQ(edges[1].curve, 1);
  EXPECT_EQ(edges[0].edge.control_points, given.control_points);
  EXPECT_EQ(edges[1].edge.degree, 6);
  EXPECT_LE(worst_deviation(s, s.trim_loops[0].curves[1].uv, edges[1].edge), 1e-12 * diagonal(s));
  s.trim_loops[0].curves[1].uv = uv_polyline({{0.5, 0.9}, {0.1, 0.1}});
  EXPECT_THROW(trim_edges(s), std::invalid_argument);
}

}  // namespace
}  // namespace nurbsreg::engine
