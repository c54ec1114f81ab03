// Point projection onto NURBS curves, one core: circular clipping (seed paper 002) versus
// Ma & Hewitt (seed paper 000) on the six kinds of test curve of seed 002's Fig. 4 / Table 1
// (cubic, quartic, quintic Bézier; cubic, quartic, sextic rational Bézier), with test points
// on offset curves at +-2% and +-10% of the bounding-box diagonal. Counters: subdivisions and
// Newton evaluations per point. See bench/README.md for the command, bench/HISTORY.md ("Curves")
// for results.
#include <benchmark/benchmark.h>

#include <cmath>
#include <string>
#include <vector>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/curve_projection.hpp"

namespace {

using nurbsreg::engine::Aabb;
using nurbsreg::engine::CurveHit;
using nurbsreg::engine::CurveProjectionStats;
using nurbsreg::engine::CurveProjector;
using nurbsreg::engine::CurveStrategy;
using nurbsreg::engine::NurbsCurve;
using nurbsreg::engine::Vec3;

NurbsCurve bezier(std::vector<Vec3> points, std::vector<double> weights = {}) {
  NurbsCurve c;
  c.degree = static_cast<int>(points.size()) - 1;
  c.dimension = 2;
  c.knots.assign(c.degree + 1, 0.0);
  c.knots.insert(c.knots.end(), c.degree + 1, 1.0);
  c.control_points = std::move(points);
  c.weights = std::move(weights);
  return c;
}

// Seed 002's figures are not in the text; these are curves of the same kinds. The quartic is
// the one whose control points the paper does give (Fig. 5).
NurbsCurve test_curve(int which) {
  switch (which) {
    case 0:  // cubic Bézier, S-shaped
      return bezier({{0, 0, 0}, {1, 3, 0}, {3, -2, 0}, {4, 1, 0}});
    case 1:  // quartic Bézier of Fig. 5
      return bezier({{-3.6164, -18.7790, 0},
                     {3.7808, 26.5070, 0},
                     {-0.6575, -45.9815, 0},
                     {-2.2353, 44.1267, 0},
                     {17.1765, -1.4683, 0}});
    case 2:  // quintic Bézier, two bumps
      return bezier({{0, 0, 0}, {1, 3, 0}, {2, -2, 0}, {3, 3, 0}, {4, -2, 0}, {5, 1, 0}});
    case 3:  // cubic rational
      return bezier({{0, 0, 0}, {1, 3, 0}, {3, 3, 0}, {4, 0, 0}}, {1, 3, 0.5, 1});
    case 4:  // quartic rational, a hook
      return bezier({{0, 0, 0}, {2, 4, 0}, {5, 3, 0}, {4, -1, 0}, {1, 1, 0}}, {1, 0.5, 2, 0.7, 1});
    default:  // sextic rational, a wave with a loop-like turn
      return bezier({{0, 0, 0}, {1, 2, 0}, {3, -1, 0}, {2, 3, 0}, {4, 4, 0}, {5, -2, 0}, {6, 1, 0}},
                    {1, 2, 0.5, 1.5, 0.8, 3, 1});
  }
}

const char* const kNames[] = {"cubic",          "quartic",          "quintic",
                              "rational_cubic", "rational_quartic", "rational_sextic"};

// Offset-curve points C(u) +- delta N(u) (planar unit normal), u uniform in the domain.
std::vector<Vec3> offset_points(const NurbsCurve& curve, int count) {
  Aabb box;
  for (const Vec3& p : curve.control_points)
    box.extend(p);
  const double diag = box.diagonal();
  const double offsets[] = {0.02, -0.02, 0.1, -0.1};
  std::vector<Vec3> points;
  for (int i = 0; i < count; ++i) {
    const double u = (i + 0.5) / count;
    Vec3 d[2];
    curve.derivatives(u, 1, d);
    const Vec3 normal = Vec3(-d[1].y(), d[1].x(), 0.0).normalized();
    points.push_back(d[0] + offsets[i % 4] * diag * normal);
  }
  return points;
}

struct Fixture {
  CurveProjector projector;
  std::vector<Vec3> points;
};

const Fixture& fixture(int which) {
  static const std::vector<Fixture> all = [] {
    std::vector<Fixture> v;
    for (int k = 0; k < 6; ++k) {
      const NurbsCurve c = test_curve(k);
      v.push_back({CurveProjector(c), offset_points(c, 4000)});
    }
    // A long smooth space curve: 1,000 control points on a slowly winding wave, cubic, with
    // uniform interior knots (997 Bézier pieces); points offset by up to 2% of the extent.
    NurbsCurve big;
    big.degree = 3;
    big.knots.assign(4, 0.0);
    for (int i = 1; i <= 996; ++i)
      big.knots.push_back(i / 997.0);
    big.knots.insert(big.knots.end(), 4, 1.0);
    for (int i = 0; i < 1000; ++i) {
      const double a = 0.05 * i;
      big.control_points.emplace_back(0.1 * i + std::cos(a), 3.0 * std::sin(0.3 * a), std::sin(a));
    }
    std::vector<Vec3> pts;
    for (int i = 0; i < 4000; ++i) {
      pts.push_back(big.evaluate((i + 0.5) / 4000) +
                    2.0 * Vec3(std::sin(1.3 * i), std::cos(0.7 * i), std::sin(0.9 * i)));
    }
    v.push_back({CurveProjector(big), std::move(pts)});
    return v;
  }();
  return all[which];
}

// Fraction of the fixture's points where `strategy` ends farther than circular clipping
// (by more than 1e-9 of the distance scale): Ma & Hewitt's wrong answers.
double fraction_worse(const Fixture& f, CurveStrategy strategy) {
  int worse = 0;
  for (const Vec3& p : f.points) {
    const double d = std::sqrt(f.projector.project(p, strategy).distance_sq);
    const double ref = std::sqrt(f.projector.project(p).distance_sq);
    if (d > ref + 1e-9 * (1.0 + ref)) ++worse;
  }
  return static_cast<double>(worse) / static_cast<double>(f.points.size());
}

void project_points(benchmark::State& state, int which, CurveStrategy strategy) {
  const Fixture& f = fixture(which);
  if (strategy != CurveStrategy::circular_clipping) {
    state.counters["worse"] = fraction_worse(f, strategy);
  }
  CurveProjectionStats stats;
  std::size_t i = 0;
  for (auto _ : state) {
    const CurveHit hit = f.projector.project(f.points[i], strategy, &stats);
    benchmark::DoNotOptimize(hit);
    if (++i == f.points.size()) i = 0;
  }
  state.SetItemsProcessed(state.iterations());
  const double q = static_cast<double>(stats.queries);
  state.counters["subdiv/pt"] = static_cast<double>(stats.subdivisions) / q;
  state.counters["newton/pt"] = static_cast<double>(stats.newton_iterations) / q;
  state.counters["us/pt"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * 1e-6,
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

const int kRegistered = [] {
  for (int k = 0; k < 6; ++k) {
    for (CurveStrategy s : {CurveStrategy::circular_clipping, CurveStrategy::ma_hewitt}) {
      const std::string name = std::string("curve/") + kNames[k] + "/" +
                               (s == CurveStrategy::circular_clipping ? "clipping" : "ma_hewitt");
      benchmark::RegisterBenchmark(name.c_str(), project_points, k, s);
    }
  }
  benchmark::RegisterBenchmark("curve/long_1000_points/clipping", project_points, 6,
                               CurveStrategy::circular_clipping);
  return 0;
}();

}  // namespace

BENCHMARK_MAIN();
