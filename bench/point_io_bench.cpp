// Point I/O throughput (points/s) on 1,000,000 generated points in a temporary directory:
// XYZ text, PCD binary and binary_compressed, PLY binary, and a projection-results CSV with the
// contract's 11 columns. Reproduce: see bench/README.md; results: bench/HISTORY.md, "Point I/O".
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>
#include <random>

#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/point_table.hpp"

namespace {

namespace fs = std::filesystem;
using nurbsreg::engine::Vec3;
using namespace nurbsreg::io;

constexpr std::size_t kPoints = 1'000'000;

// A scan-like cloud: points on a wavy 1 m x 1 m sheet in millimetres with sensor noise.
const std::vector<Vec3>& points() {
  static const std::vector<Vec3> cloud = [] {
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> u(0.0, 1000.0);
    std::normal_distribution<double> noise(0.0, 0.05);
    std::vector<Vec3> p(kPoints);
    for (Vec3& q : p) {
      const double x = u(rng), y = u(rng);
      q = Vec3(x, y, 20.0 * std::sin(x / 100.0) * std::cos(y / 150.0) + noise(rng));
    }
    return p;
  }();
  return cloud;
}

// Projection results as `project --out R.csv` writes them.
const PointTable& results() {
  static const PointTable table = [] {
    PointTable t;
    const std::vector<Vec3>& p = points();
    auto& index = t.add_column<std::uint64_t>("index");
    auto& x = t.add_column<double>("x");
    auto& y = t.add_column<double>("y");
    auto& z = t.add_column<double>("z");
    auto& fx = t.add_column<double>("foot_x");
    auto& fy = t.add_column<double>("foot_y");
    auto& fz = t.add_column<double>("foot_z");
    auto& distance = t.add_column<double>("distance");
    auto& entity = t.add_column<std::int32_t>("entity");
    auto& u = t.add_column<double>("u");
    auto& v = t.add_column<double>("v");
    for (std::size_t i = 0; i < p.size(); ++i) {
      index.push_back(i);
      x.push_back(p[i].x());
      y.push_back(p[i].y());
      z.push_back(p[i].z());
      fx.push_back(p[i].x() + 1e-3);
      fy.push_back(p[i].y() - 1e-3);
      fz.push_back(p[i].z() * 0.999);
      distance.push_back(std::abs(p[i].z()) * 1e-3);
      entity.push_back(static_cast<std::int32_t>(i % 7));
      u.push_back(p[i].x() / 1000.0);
      v.push_back(p[i].y() / 1000.0);
    }
    return t;
  }();
  return table;
}

const fs::path& directory() {
  static const fs::path dir = [] {
    fs::path d =
        fs::temp_directory_path() / ("nurbsreg_point_io_bench_" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

std::string file(const std::string& name) {
  return (directory() / name).string();
}

void write_case(benchmark::State& state, const std::string& name, PcdEncoding encoding) {
  for (auto _ : state)
    write_point_cloud(file(name), points(), {encoding, false});
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kPoints));
  state.counters["MB"] = static_cast<double>(fs::file_size(file(name))) / 1e6;
}

void read_case(benchmark::State& state, const std::string& name, PcdEncoding encoding) {
  if (!fs::exists(file(name))) write_point_cloud(file(name), points(), {encoding, false});
  for (auto _ : state) {
    const PointCloud cloud = read_point_cloud(file(name));
    if (cloud.size() != kPoints) state.SkipWithError("wrong point count");
    benchmark::DoNotOptimize(cloud.points.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kPoints));
}

void BM_WriteXyz(benchmark::State& s) {
  write_case(s, "p.xyz", PcdEncoding::binary);
}
void BM_ReadXyz(benchmark::State& s) {
  read_case(s, "p.xyz", PcdEncoding::binary);
}
void BM_WritePcdBinary(benchmark::State& s) {
  write_case(s, "b.pcd", PcdEncoding::binary);
}
void BM_ReadPcdBinary(benchmark::State& s) {
  read_case(s, "b.pcd", PcdEncoding::binary);
}
void BM_WritePcdCompressed(benchmark::State& s) {
  write_case(s, "c.pcd", PcdEncoding::binary_compressed);
}
void BM_ReadPcdCompressed(benchmark::State& s) {
  read_case(s, "c.pcd", PcdEncoding::binary_compressed);
}
void BM_WritePcdAscii(benchmark::State& s) {
  write_case(s, "a.pcd", PcdEncoding::ascii);
}
void BM_ReadPcdAscii(benchmark::State& s) {
  read_case(s, "a.pcd", PcdEncoding::ascii);
}
void BM_WritePly(benchmark::State& s) {
  write_case(s, "p.ply", PcdEncoding::binary);
}
void BM_ReadPly(benchmark::State& s) {
  read_case(s, "p.ply", PcdEncoding::binary);
}

void BM_WriteResultsCsv(benchmark::State& state) {
  const PointTable& table = results();
  for (auto _ : state)
    write_csv(file("r.csv"), table);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kPoints));
  state.counters["MB"] = static_cast<double>(fs::file_size(file("r.csv"))) / 1e6;
}
void BM_ReadResultsCsvAsCloud(benchmark::State& state) {
  if (!fs::exists(file("r.csv"))) write_csv(file("r.csv"), results());
  for (auto _ : state) {
    const PointCloud cloud = read_point_cloud(file("r.csv"));
    if (cloud.size() != kPoints) state.SkipWithError("wrong point count");
    benchmark::DoNotOptimize(cloud.points.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kPoints));
}
void BM_WriteResultsPcd(benchmark::State& state) {
  PointTable table;  // x, y, z first, as write_pcd requires
  for (const char* name :
       {"x", "y", "z", "index", "foot_x", "foot_y", "foot_z", "distance", "entity", "u", "v"}) {
    std::visit([&](const auto& v) { table.add_column(name, v); }, results().find(name)->values);
  }
  for (auto _ : state)
    write_pcd(file("r.pcd"), table);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kPoints));
  state.counters["MB"] = static_cast<double>(fs::file_size(file("r.pcd"))) / 1e6;
}

#define POINT_IO(fn) BENCHMARK(fn)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime()
POINT_IO(BM_WriteXyz);
POINT_IO(BM_ReadXyz);
POINT_IO(BM_WritePcdBinary);
POINT_IO(BM_ReadPcdBinary);
POINT_IO(BM_WritePcdCompressed);
POINT_IO(BM_ReadPcdCompressed);
POINT_IO(BM_WritePcdAscii);
POINT_IO(BM_ReadPcdAscii);
POINT_IO(BM_WritePly);
POINT_IO(BM_ReadPly);
POINT_IO(BM_WriteResultsCsv);
POINT_IO(BM_ReadResultsCsvAsCloud);
POINT_IO(BM_WriteResultsPcd);

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::error_code ignored;
  fs::remove_all(directory(), ignored);
  return 0;
}
