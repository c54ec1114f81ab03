// Surface point projection throughput (points/s) per strategy, on one strongly curved bicubic
// patch (seed 001 Fig. 3/4 style) and on a 49-patch bicubic panel (10 x 10 control points), with
// points near the surface (90%) and far from it (10%). Counters: subdivisions and Newton
// iterations per point. The *_recompute variant rebuilds the patch's squared-distance
// coefficients from the control points for every point, to show what the per-patch cache saves.
//
//   build/bench/surface_projection_bench --benchmark_min_time=0.2
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>

#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/engine/surface_projection.hpp"
#include "support/random_entities.hpp"

namespace {

using namespace nurbsreg::engine;
using nurbsreg::test::uniform;

NurbsSurface single_patch() {
  const double z[4][4] = {{0, 3, -3, 0}, {3, -6, 6, -3}, {-3, 6, -6, 3}, {0, -3, 3, 0}};
  return nurbsreg::test::bicubic_patch("curved_bicubic",
                                       [&](int i, int j) { return Vec3(i, j, z[i][j]); });
}

// 10 x 10 control points, uniform knots: 7 x 7 = 49 bicubic Bézier patches; a wavy panel.
NurbsSurface panel() {
  NurbsSurface s;
  s.name = "panel";
  s.degree_u = s.degree_v = 3;
  s.count_u = s.count_v = 10;
  std::vector<double> knots = {0, 0, 0, 0};
  for (int k = 1; k < 7; ++k)
    knots.push_back(k / 7.0);
  knots.insert(knots.end(), {1, 1, 1, 1});
  s.knots_u = s.knots_v = knots;
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 10; ++j) {
      s.control_points.emplace_back(i, j, 1.5 * std::sin(0.9 * i) * std::cos(0.7 * j));
    }
  }
  return s;
}

// The panel with weights in [0.5, 2]: a rational (NURBS) panel of the same shape class.
NurbsSurface rational_panel() {
  NurbsSurface s = panel();
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 10; ++j)
      s.weights.push_back(std::pow(2.0, std::sin(1.3 * i + 0.7 * j)));
  }
  return s;
}

std::vector<Vec3> points_for(const NurbsSurface& s, int count) {
  std::mt19937_64 rng(2024);
  const SurfaceProjector projector(s);
  const Aabb box = projector.box();
  std::vector<Vec3> points;
  for (int k = 0; k < count; ++k) {
    if (k % 10 == 9) {  // far
      points.push_back(box.center() +
                       5 * box.diagonal() *
                           Vec3(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1)));
      continue;
    }
    const double u = uniform(rng, 0, 1), v = uniform(rng, 0, 1);
    const SurfaceDerivatives d = s.derivatives(u, v);
    const Vec3 n = d.su.cross(d.sv).normalized();
    points.push_back(d.s + uniform(rng, -0.3, 0.3) * n);
  }
  return points;
}

void report(benchmark::State& state, const SurfaceProjectionStats& stats, std::size_t points) {
  const double n = static_cast<double>(points);
  state.SetItemsProcessed(static_cast<std::int64_t>(points));
  state.counters["subdiv/pt"] = stats.subdivisions / n;
  state.counters["newton/pt"] = stats.newton_iterations / n;
  state.counters["depth_hits"] = static_cast<double>(stats.depth_limit_hits);
}

void run(benchmark::State& state, const NurbsSurface& s, SurfaceStrategy strategy) {
  const SurfaceProjector projector(s);
  const std::vector<Vec3> points = points_for(s, 1000);
  SurfaceScratch scratch;
  SurfaceProjectionStats stats;
  std::size_t done = 0;
  double sink = 0;
  for (auto _ : state) {
    const Vec3& p = points[done % points.size()];
    const SurfaceHit hit = projector.project(p, strategy, scratch, &stats);
    sink += hit.distance_sq;
    ++done;
  }
  benchmark::DoNotOptimize(sink);
  report(state, stats, done);
}

// The same clipping, but every visited patch is re-prepared (D, G, E from the control points, as
// a method without the cache would do per point).
void run_recompute(benchmark::State& state, const NurbsSurface& s) {
  const SurfaceProjector projector(s);
  const std::vector<Vec3> points = points_for(s, 1000);
  SurfaceScratch scratch;
  SurfaceProjectionStats stats;
  std::size_t done = 0;
  double sink = 0;
  std::vector<std::pair<double, int>> order;
  for (auto _ : state) {
    const Vec3& p = points[done % points.size()];
    SurfaceHit best;
    // Same visiting order and pruning as SurfaceProjector::project.
    order.clear();
    for (int k = 0; k < static_cast<int>(projector.patches().size()); ++k) {
      const PreparedPatch& pp = projector.patches()[k];
      const double to_sphere = std::max(0.0, (p - pp.sphere.center).norm() - pp.sphere.radius);
      order.emplace_back(std::max(pp.box.squared_distance(p), to_sphere * to_sphere), k);
    }
    std::sort(order.begin(), order.end());
    for (const auto& [lower, k] : order) {
      if (lower > best.distance_sq) break;
      const PreparedPatch fresh = prepare_patch(projector.patches()[k].patch);
      project_onto_patch(fresh, p, best, scratch, &stats);
    }
    sink += best.distance_sq;
    ++done;
  }
  benchmark::DoNotOptimize(sink);
  report(state, stats, done);
}

// Per-point coefficient cost alone: cached (49 x a few flops) vs from the control points
// (N_ij = Σ β w w (P_ab - p)·(P_cd - p): 256 terms for bicubic).
void coefficients_cached(benchmark::State& state) {
  const PreparedPatch pp = SurfaceProjector(single_patch()).patches()[0];
  const std::vector<Vec3> points = points_for(single_patch(), 1000);
  double out[49];
  std::size_t k = 0;
  for (auto _ : state) {
    pp.numerator(points[k++ % points.size()], out);
    benchmark::DoNotOptimize(out);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(k));
}

void coefficients_from_control_points(benchmark::State& state) {
  const PreparedPatch pp = SurfaceProjector(single_patch()).patches()[0];
  const std::vector<Vec3> points = points_for(single_patch(), 1000);
  const BezierPatch& b = pp.patch;
  double beta[4][4][4][4];
  auto binom = [](int n, int r) {
    double x = 1;
    for (int i = 1; i <= r; ++i)
      x = x * (n - r + i) / i;
    return x;
  };
  for (int a = 0; a < 4; ++a)
    for (int c = 0; c < 4; ++c)
      for (int bb = 0; bb < 4; ++bb)
        for (int d = 0; d < 4; ++d)
          beta[a][c][bb][d] = binom(3, a) * binom(3, c) * binom(3, bb) * binom(3, d) /
                              (binom(6, a + c) * binom(6, bb + d));
  double out[49];
  std::size_t k = 0;
  for (auto _ : state) {
    const Vec3& p = points[k++ % points.size()];
    Vec3 rel[16];
    double w[16];
    for (int i = 0; i < 16; ++i) {
      w[i] = b.cw[i][3];
      rel[i] = w[i] * (b.cw[i].head<3>() / w[i] - p);
    }
    for (double& x : out)
      x = 0;
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 4; ++c)
        for (int bb = 0; bb < 4; ++bb)
          for (int d = 0; d < 4; ++d)
            out[(a + c) * 7 + bb + d] += beta[a][c][bb][d] * rel[a * 4 + bb].dot(rel[c * 4 + d]);
    benchmark::DoNotOptimize(out);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(k));
}

void BM_patch_clipping(benchmark::State& s) {
  run(s, single_patch(), SurfaceStrategy::spherical_clipping);
}
void BM_patch_ma_hewitt(benchmark::State& s) {
  run(s, single_patch(), SurfaceStrategy::ma_hewitt);
}
void BM_patch_clipping_recompute(benchmark::State& s) {
  run_recompute(s, single_patch());
}
void BM_panel49_clipping(benchmark::State& s) {
  run(s, panel(), SurfaceStrategy::spherical_clipping);
}
void BM_panel49_ma_hewitt(benchmark::State& s) {
  run(s, panel(), SurfaceStrategy::ma_hewitt);
}
void BM_panel49_clipping_recompute(benchmark::State& s) {
  run_recompute(s, panel());
}
void BM_rational_panel49_clipping(benchmark::State& s) {
  run(s, rational_panel(), SurfaceStrategy::spherical_clipping);
}
void BM_sphere_clipping(benchmark::State& s) {
  run(s, make_sphere(Vec3(0, 0, 0), 1.0), SurfaceStrategy::spherical_clipping);
}
void BM_coefficients_cached(benchmark::State& s) {
  coefficients_cached(s);
}
void BM_coefficients_from_control_points(benchmark::State& s) {
  coefficients_from_control_points(s);
}

BENCHMARK(BM_patch_clipping);
BENCHMARK(BM_patch_ma_hewitt);
BENCHMARK(BM_patch_clipping_recompute);
BENCHMARK(BM_panel49_clipping);
BENCHMARK(BM_panel49_ma_hewitt);
BENCHMARK(BM_panel49_clipping_recompute);
BENCHMARK(BM_rational_panel49_clipping);
BENCHMARK(BM_sphere_clipping);
BENCHMARK(BM_coefficients_cached);
BENCHMARK(BM_coefficients_from_control_points);

}  // namespace

BENCHMARK_MAIN();
