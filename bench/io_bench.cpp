// io throughput: projection tables (CSV and binary PCD) written and read for N rows, and model
// JSON parsing. Files go to the system temp directory; run with
//   build/bench/io_bench --benchmark_min_time=1
// Rows/s are reported as items_per_second, file sizes as bytes_per_second.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <random>

#include "nurbsreg/io/cad_import.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "nurbsreg/io/projection_results.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::io {
namespace {

ProjectionTable make_table(std::size_t rows) {
  std::mt19937_64 rng(1);
  ProjectionTable t;
  for (std::size_t r = 0; r < rows; ++r) {
    t.index.push_back(r);
    const engine::Vec3 p(test::uniform(rng, -500, 500), test::uniform(rng, -500, 500),
                         test::uniform(rng, -500, 500));
    const engine::Vec3 n(test::uniform(rng, -1, 1), test::uniform(rng, -1, 1),
                         test::uniform(rng, -1, 1));
    t.point.push_back(p);
    t.foot.push_back(p + 0.01 * n);
    t.distance.push_back(0.01 * n.norm());
    t.entity.push_back(static_cast<std::int32_t>(rng() % 64));
    t.u.push_back(test::uniform(rng, 0, 1));
    t.v.push_back(test::uniform(rng, 0, 1));
  }
  return t;
}

std::string temp_path(const char* name) {
  return (std::filesystem::temp_directory_path() / name).string();
}

void BM_WriteProjection(benchmark::State& state, const char* name) {
  const ProjectionTable table = make_table(static_cast<std::size_t>(state.range(0)));
  const ProjectionColumns columns = table.columns();
  const std::string path = temp_path(name);
  for (auto _ : state)
    write_projection_results(path, columns);
  state.SetItemsProcessed(state.iterations() * state.range(0));
  state.SetBytesProcessed(state.iterations() *
                          static_cast<std::int64_t>(std::filesystem::file_size(path)));
  std::filesystem::remove(path);
}

void BM_ReadProjection(benchmark::State& state, const char* name) {
  const std::string path = temp_path(name);
  write_projection_results(path, make_table(static_cast<std::size_t>(state.range(0))).columns());
  for (auto _ : state)
    benchmark::DoNotOptimize(read_projection_results(path));
  state.SetItemsProcessed(state.iterations() * state.range(0));
  state.SetBytesProcessed(state.iterations() *
                          static_cast<std::int64_t>(std::filesystem::file_size(path)));
  std::filesystem::remove(path);
}

BENCHMARK_CAPTURE(BM_WriteProjection, csv, "nurbsreg_bench.csv")
    ->Arg(1 << 20)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_WriteProjection, pcd, "nurbsreg_bench.pcd")
    ->Arg(1 << 20)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ReadProjection, csv, "nurbsreg_bench_r.csv")
    ->Arg(1 << 20)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ReadProjection, pcd, "nurbsreg_bench_r.pcd")
    ->Arg(1 << 20)
    ->Unit(benchmark::kMillisecond);

// A model of `surfaces` rational bicubic surfaces with 20 x 20 control points each.
void BM_ParseModel(benchmark::State& state) {
  engine::Model model;
  for (int k = 0; k < state.range(0); ++k) {
    model.surfaces.push_back(
        test::random_surface(static_cast<std::uint64_t>(k), 3, 3, 20, 20, true));
  }
  const std::string text = model_to_json(model);
  for (auto _ : state)
    benchmark::DoNotOptimize(parse_model(text, "bench.json"));
  state.SetItemsProcessed(state.iterations() * state.range(0) * 400);  // control points
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(text.size()));
}
BENCHMARK(BM_ParseModel)->Arg(100)->Unit(benchmark::kMillisecond);

// Real CAD from shared/data (next to the checkout, as in CI); skipped when it is absent.
std::string shared_file(const char* relative) {
  const auto root = std::filesystem::path(__FILE__).parent_path().parent_path().parent_path();
  return (root / "shared" / "data" / "real" / relative).string();
}

void BM_ReadCad(benchmark::State& state, const char* relative) {
  const std::string path = shared_file(relative);
  if (!std::filesystem::exists(path)) {
    state.SkipWithError("shared data not found");
    return;
  }
  std::size_t surfaces = 0;
  for (auto _ : state) {
    const engine::Model m = read_cad_file(path);
    surfaces = m.surfaces.size();
  }
  state.counters["surfaces"] = static_cast<double>(surfaces);
  state.SetBytesProcessed(state.iterations() *
                          static_cast<std::int64_t>(std::filesystem::file_size(path)));
}
BENCHMARK_CAPTURE(BM_ReadCad, nist_step, "nist/nist_ctc_02_asme1_ap242-1.stp")
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ReadCad, linkrods_step, "occt/linkrods.step")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ReadCad, bearing_iges, "occt/bearing.iges")->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace nurbsreg::io

BENCHMARK_MAIN();
