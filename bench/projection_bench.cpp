// Frame projection throughput of the engine (Projector::project over a PreparedModel: BVH
// best-first over all patches, exact spherical clipping per patch, TBB over points), per example
// model, cold (no hints) and warm (hints = the feet of the same points before a 0.01 mm
// perturbation, as in an ICP iteration), with 1 and 2 threads (tbb::global_control).
// Points: half area samples moved along the normal by up to +-2 mm, half uniform in the model's
// bounding box enlarged by 10% (deterministic seeds).
// panel_trimmed: the panel as a trimmed face (an outer loop inset 3% from the domain and a
// 5-point star hole of degree-1 uv curves), same points as panel: trimmed vs untrimmed cost.
// Counters: items_per_second (points/s, wall), patches visited and subdivisions per point.
// On a loaded machine read the CPU time column (Google Benchmark reports both) or count
// instructions: valgrind --tool=callgrind build/bench/projection_bench --benchmark_filter=...
//
//   build/bench/projection_bench --benchmark_min_time=0.5
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "support/polygon_loop.hpp"
#include "support/source_paths.hpp"

namespace {

using namespace nurbsreg::engine;

constexpr std::size_t kPoints = 20000;

struct Fixture {
  std::unique_ptr<PreparedModel> model;
  std::vector<Vec3> points;
  std::vector<Vec3> perturbed;
  std::vector<ProjectionHint> hints;  // feet of `perturbed`
};

using nurbsreg::test::polygon_loop;

void trim_every_surface(Model& model) {
  for (NurbsSurface& s : model.surfaces) {
    const ParamInterval du = s.domain_u(), dv = s.domain_v();
    auto at = [&](double a, double b) { return Vec2(du.to_parent(a), dv.to_parent(b)); };
    s.trim_loops.push_back(
        polygon_loop({at(0.03, 0.03), at(0.97, 0.03), at(0.97, 0.97), at(0.03, 0.97)}));
    std::vector<Vec2> star;
    for (int k = 0; k < 10; ++k) {
      const double angle = 0.3 + 3.14159265358979323846 * k / 5.0;
      const double r = k % 2 == 0 ? 0.3 : 0.12;
      star.push_back(at(0.5 + r * std::cos(angle), 0.45 + r * std::sin(angle)));
    }
    s.trim_loops.push_back(polygon_loop(star));
  }
}

Fixture& fixture(const std::string& name) {
  static std::map<std::string, std::unique_ptr<Fixture>> cache;
  auto& slot = cache[name];
  if (slot) return *slot;
  slot = std::make_unique<Fixture>();
  Fixture& f = *slot;
  const std::string suffix = "_trimmed";
  const bool trimmed = name.size() > suffix.size() &&
                       name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
  const std::string file = trimmed ? name.substr(0, name.size() - suffix.size()) : name;
  Model model =
      nurbsreg::io::read_model_json(nurbsreg::test::examples_dir() + "/" + file + ".json");
  if (trimmed) trim_every_surface(model);
  f.model = std::make_unique<PreparedModel>(std::move(model));
  std::mt19937_64 rng(20261122);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const std::size_t near = kPoints / 2;
  for (const SurfaceSample& s : sample_surfaces(f.model->model(), near, 7)) {
    f.points.push_back(s.point + (4.0 * unit(rng) - 2.0) * s.normal);
  }
  Aabb box = f.model->bounds();
  const Vec3 pad = 0.05 * (box.hi - box.lo);
  const Vec3 lo = box.lo - pad, size = (box.hi - box.lo) + 2.0 * pad;
  while (f.points.size() < kPoints) {
    f.points.push_back(lo + Vec3(unit(rng), unit(rng), unit(rng)).cwiseProduct(size));
  }
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (const Vec3& p : f.points) {
    Vec3 dir(gauss(rng), gauss(rng), gauss(rng));
    f.perturbed.push_back(p + 0.01 * dir.normalized());
  }
  Projector projector(*f.model);
  ProjectionResults results;
  projector.project_serial(PointView::of(f.perturbed), {}, results);  // not in profiles
  for (std::size_t i = 0; i < results.size(); ++i)
    f.hints.push_back(results.hint(i));
  return f;
}

void run(benchmark::State& state, const std::string& name, bool warm) {
  Fixture& f = fixture(name);
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(state.range(0)));
  Projector projector(*f.model);
  ProjectionResults results;
  ProjectionCounters counters;
  std::span<const ProjectionHint> hints;
  if (warm) hints = f.hints;
  for (auto _ : state) {
    projector.project(PointView::of(f.points), {}, results, hints, &counters);
    benchmark::DoNotOptimize(results.distance.data());
  }
  std::size_t failed = 0;
  for (ProjectionStatus s : results.status)
    failed += s != ProjectionStatus::ok;
  const double n = static_cast<double>(f.points.size());
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * f.points.size()));
  state.counters["patches/pt"] = static_cast<double>(counters.patches_visited) / n;
  state.counters["subdiv/pt"] = static_cast<double>(counters.subdivisions) / n;
  state.counters["newton/pt"] = static_cast<double>(counters.newton_iterations) / n;
  state.counters["failed"] = static_cast<double>(failed);
}

}  // namespace

#define NURBSREG_PROJECTION_BENCH(model)                                              \
  BENCHMARK_CAPTURE(run, model##_cold, #model, false)->Arg(1)->Arg(2)->UseRealTime(); \
  BENCHMARK_CAPTURE(run, model##_warm, #model, true)->Arg(1)->Arg(2)->UseRealTime();

NURBSREG_PROJECTION_BENCH(panel)
NURBSREG_PROJECTION_BENCH(panel_trimmed)
NURBSREG_PROJECTION_BENCH(panel_1369)
NURBSREG_PROJECTION_BENCH(sphere)
NURBSREG_PROJECTION_BENCH(folded)

BENCHMARK_MAIN();
