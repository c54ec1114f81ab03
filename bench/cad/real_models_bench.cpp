// real_models_bench: every real CAD model of shared/data/real (and the examples) as a new user
// meets it (issue 26, item 1): conversion, a load from the model cache, preparation, the trimmed
// faces' bounds, peak memory; exact projection of 1 M near points (a synthetic scan, noise 0.5% of
// the diagonal) and of 1 M mixed points (half of those, half anywhere in the box enlarged by 10%
// of its diagonal); a 1 M-point alignment (the scan 3 degrees and 2% of the diagonal off); and
// OpenCASCADE's BRepExtrema_DistShapeShape on a subset of the mixed points, in the same run.
// The projections run as a user's `project` does (chained cold frames, ProjectionOptions::
// chain_cold), alternating with the same points searched separately (chain_cold off).
// Then the profile: where a point's time goes (engine::ProjectionCounters per point).
//
//   build/bench/cad/real_models_bench [--models bearing,linkrods,...] [--points 1000000]
//       [--occt-points 100] [--threads 2] [--repeat 2] [--skip-align]
//
// Times are wall clock on the given number of threads, the fastest of --repeat runs, near and
// mixed runs alternating (the machine may be shared: the counts per point are exact, the times
// are not). Exit status 1 when 1 and 2 threads disagree on a point (bit for bit), 2 on usage.

#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <BRepBuilderAPI_MakeVertex.hxx>
#include <BRepExtrema_DistShapeShape.hxx>
#include <CLI/CLI.hpp>
#include <Standard_Failure.hxx>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "support/cad_reference.hpp"
#include "support/source_paths.hpp"

namespace engine = nurbsreg::engine;
namespace io = nurbsreg::io;
namespace icp = nurbsreg::icp;
using engine::Vec3;

namespace {

double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Peak resident memory since the last reset (Linux: VmHWM, reset through clear_refs), in MB.
void reset_peak_memory() {
  std::ofstream("/proc/self/clear_refs") << "5";
}
double peak_memory_mb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  return 0.0;
}

struct ModelFile {
  std::string name, path;
  bool cad = false;
};

std::vector<ModelFile> all_models(const std::string& data, const std::string& examples) {
  std::vector<ModelFile> out;
  namespace fs = std::filesystem;
  std::vector<fs::path> paths;
  for (const auto& e : fs::recursive_directory_iterator(data)) {
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (ext == ".step" || ext == ".stp" || ext == ".iges" || ext == ".igs")
      paths.push_back(e.path());
  }
  std::sort(paths.begin(), paths.end());
  for (const fs::path& p : paths)
    out.push_back(
        {p.parent_path().filename().string() + "/" + p.filename().string(), p.string(), true});
  for (const char* json : {"panel.json", "panel_1369.json", "rational_panel.json", "sphere.json",
                           "torus.json", "folded.json"})
    out.push_back({std::string("examples/") + json, examples + "/" + json, false});
  return out;
}

struct Profile {  // per point
  double items = 0, patches = 0, trimmed = 0, rational = 0, edges = 0, subdivisions = 0, newton = 0,
         region_drops = 0, region_rejections = 0, certified = 0;
};
Profile per_point(const engine::ProjectionCounters& c) {
  const double n = std::max<double>(1.0, static_cast<double>(c.points - c.skipped));
  Profile p;
  p.items = c.patches_visited / n;
  p.edges = c.edge_pieces_visited / n;
  p.patches = (c.patches_visited - c.edge_pieces_visited) / n;
  p.trimmed = c.trimmed_patches_visited / n;
  p.rational = c.rational_patches_visited / n;
  p.subdivisions = c.subdivisions / n;
  p.newton = c.newton_iterations / n;
  p.region_drops = c.region_drops / n;
  p.region_rejections = c.region_rejections / n;
  p.certified = (c.certified + c.reach_proven) / n;
  return p;
}

struct Row {
  ModelFile file;
  std::string error;
  std::size_t faces = 0, patches = 0, boundary_patches = 0, rational_patches = 0, edge_pieces = 0;
  int max_degree = 0;
  double convert_s = NAN, cache_s = NAN, prepare_s = NAN, bounds_s = NAN, memory_mb = NAN;
  double diagonal = 0, control_diagonal = 0;
  std::string bounds_kind;
  double near_rate = NAN, mixed_rate = NAN, align_s = NAN, occt_rate = NAN;
  double near_cpu_rate = NAN, mixed_cpu_rate = NAN, align_cpu_s = NAN;
  // The same points with a separate search per point (ProjectionOptions::chain_cold off), in the
  // same runs, and the share of answers the chained runs proved by near lists.
  double near_separate_rate = NAN, mixed_separate_rate = NAN;
  double near_listed = NAN, mixed_listed = NAN;
  int align_iterations = 0;
  bool align_converged = false;
  double align_rms = NAN;
  Profile near, mixed, warm;
  bool threads_agree = true;
};

struct Options {
  std::vector<std::string> models;
  std::size_t points = 1000000;
  std::size_t occt_points = 100;
  std::size_t occt_max_faces = 600;
  int threads = 2;
  int repeat = 2;
  bool skip_align = false;
  std::string data = nurbsreg::test::shared_dir() + "/data/real";
  std::string examples = nurbsreg::test::examples_dir();
};

void project_timed(tbb::task_arena& arena, const engine::PreparedModel& prepared,
                   const std::vector<Vec3>& points, bool chained, engine::ProjectionResults& out,
                   engine::ProjectionCounters& counters, double& best, double& best_cpu) {
  const double c = process_cpu_seconds();
  const double t = now();
  engine::ProjectionOptions options;
  options.chain_cold = chained;
  arena.execute([&] {
    engine::Projector projector(prepared);  // cold: empty scratch, no hints
    projector.project(engine::PointView::of(points), options, out, {}, &counters);
  });
  best = std::min(best, now() - t);
  best_cpu = std::min(best_cpu, process_cpu_seconds() - c);
}

Row run_model(const ModelFile& file, const Options& opt, const std::string& cache_dir) {
  Row row;
  row.file = file;
  reset_peak_memory();
  engine::Model model;
  try {
    io::ModelFileOptions no_cache;
    no_cache.cache.enabled = false;
    double t = now();
    model = io::read_model_file(file.path, no_cache);
    row.convert_s = now() - t;
    if (file.cad) {
      io::ModelFileOptions cached;
      cached.cache.enabled = true;
      cached.cache.directory = cache_dir;
      io::read_model_file(file.path, cached);  // stores the entry (a conversion, untimed)
      t = now();
      model = io::read_model_file(file.path, cached);
      row.cache_s = now() - t;
    }
  } catch (const std::exception& e) {
    row.error = e.what();
    return row;
  }
  if (model.surfaces.empty()) {
    row.error = "no surfaces";
    return row;
  }
  // On --threads threads (the regions and trim edges are built a task per face).
  tbb::task_arena arena(opt.threads);
  double t = now();
  std::optional<engine::PreparedModel> prepared_storage;
  arena.execute([&] { prepared_storage.emplace(model); });
  const engine::PreparedModel& prepared = *prepared_storage;
  row.prepare_s = now() - t;
  t = now();
  const engine::ModelBounds& bounds = prepared.geometry_bounds();
  row.bounds_s = now() - t;
  row.diagonal = bounds.box.diagonal();
  row.control_diagonal = prepared.bounds().diagonal();
  row.bounds_kind = bounds.exact ? "exact" : "proven";
  row.faces = model.surfaces.size();
  for (std::size_t i = 0; i < prepared.patch_count(); ++i) {
    if (prepared.patch_class(i) == engine::RegionClass::outside) continue;
    ++row.patches;
    row.boundary_patches += prepared.patch_class(i) == engine::RegionClass::boundary;
    row.rational_patches += prepared.patch(i).rational;
    row.max_degree = std::max(
        {row.max_degree, prepared.patch(i).patch.degree_u, prepared.patch(i).patch.degree_v});
  }
  row.edge_pieces = prepared.edge_piece_count();

  // The points: a synthetic scan (area-uniform on the trimmed faces, noise along the normal).
  engine::SyntheticScanOptions synth;
  synth.points = opt.points;
  synth.noise_sigma = 0.005 * row.diagonal;
  synth.seed = 26;
  const std::vector<Vec3> near = engine::make_synthetic_scan(model, synth).points;
  std::vector<Vec3> mixed(near.begin(),
                          near.begin() + static_cast<std::ptrdiff_t>(near.size() / 2));
  {
    std::mt19937_64 rng(2026);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const Vec3 margin = Vec3::Constant(0.1 * row.diagonal);
    const Vec3 lo = bounds.box.lo - margin, extent = bounds.box.hi + margin - lo;
    while (mixed.size() < near.size())
      mixed.push_back(lo + Vec3(u(rng) * extent.x(), u(rng) * extent.y(), u(rng) * extent.z()));
  }

  engine::ProjectionResults out;
  engine::ProjectionCounters near_counters, mixed_counters;
  double near_s = INFINITY, mixed_s = INFINITY, near_cpu = INFINITY, mixed_cpu = INFINITY;
  double near_separate_s = INFINITY, mixed_separate_s = INFINITY, unused_cpu = INFINITY;
  engine::ProjectionCounters separate_counters;
  for (int r = 0; r < std::max(1, opt.repeat); ++r) {  // alternating
    project_timed(arena, prepared, near, true, out, near_counters, near_s, near_cpu);
    project_timed(arena, prepared, near, false, out, separate_counters, near_separate_s,
                  unused_cpu);
    project_timed(arena, prepared, mixed, false, out, separate_counters, mixed_separate_s,
                  unused_cpu);
    project_timed(arena, prepared, mixed, true, out, mixed_counters, mixed_s, mixed_cpu);
  }
  row.near_separate_rate = near.size() / near_separate_s;
  row.mixed_separate_rate = mixed.size() / mixed_separate_s;
  row.near_listed = static_cast<double>(near_counters.listed) / near.size();
  row.mixed_listed = static_cast<double>(mixed_counters.listed) / mixed.size();
  row.near_rate = near.size() / near_s;
  row.mixed_rate = mixed.size() / mixed_s;
  row.near_cpu_rate = near.size() / near_cpu;
  row.mixed_cpu_rate = mixed.size() / mixed_cpu;
  row.near = per_point(near_counters);
  row.mixed = per_point(mixed_counters);
  // 1 thread against `threads`, bit for bit, on a prefix of the mixed points (a chained frame's
  // answers depend on the frame's other points, so both project the same prefix).
  {
    const std::size_t n = std::min<std::size_t>(mixed.size(), 20000);
    const std::vector<Vec3> prefix(mixed.begin(), mixed.begin() + static_cast<std::ptrdiff_t>(n));
    engine::ProjectionResults one;
    tbb::task_arena single(1);
    single.execute([&] {
      engine::Projector projector(prepared);
      projector.project(engine::PointView::of(prefix), {}, one);
    });
    arena.execute([&] {
      engine::Projector projector(prepared);
      projector.project(engine::PointView::of(prefix), {}, out);
    });
    for (std::size_t i = 0; i < n; ++i) {
      const bool same = one.status[i] == out.status[i] &&
                        (std::isnan(one.distance[i]) ? std::isnan(out.distance[i])
                                                     : one.distance[i] == out.distance[i]) &&
                        one.entity[i] == out.entity[i] && one.u[i] == out.u[i] &&
                        one.v[i] == out.v[i];
      row.threads_agree = row.threads_agree && same;
    }
  }

  if (!opt.skip_align) {
    engine::SyntheticScanOptions scan = synth;
    scan.seed = 27;
    const double d = 0.02 * row.diagonal / std::sqrt(3.0);
    scan.T_scan_model = engine::pose_from_euler_degrees(2.0, 1.5, 1.5, Vec3(d, d, d));
    const engine::SyntheticScan s = engine::make_synthetic_scan(model, scan);
    arena.execute([&] {
      icp::ModelCorrespondenceFinder finder(prepared);
      icp::IcpSolver solver;
      const double t0 = now(), c0 = process_cpu_seconds();
      const icp::IcpResult result = solver.align(finder, s.points, Eigen::Isometry3d::Identity());
      row.align_s = now() - t0;
      row.align_cpu_s = process_cpu_seconds() - c0;
      row.align_iterations = result.iterations;
      row.align_converged = result.converged();
      row.align_rms = result.rms;
      row.warm = per_point(finder.last_counters());
    });
  }
  row.memory_mb = peak_memory_mb();

  // OpenCASCADE on a subset of the mixed points: one BRepExtrema_DistShapeShape per point.
  if (file.cad && opt.occt_points > 0 && row.faces <= opt.occt_max_faces) {
    try {
      const nurbsreg::test::CadShape shape = nurbsreg::test::read_cad_shape(file.path);
      const std::size_t n = std::min(opt.occt_points, mixed.size());
      // Every other point of the first 2n: near and anywhere alike.
      std::vector<Vec3> subset;
      for (std::size_t i = 0; i < n; ++i)
        subset.push_back(i % 2 == 0 ? mixed[i] : mixed[mixed.size() / 2 + i]);
      const double t0 = now();
      arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              try {
                                BRepExtrema_DistShapeShape dss(
                                    BRepBuilderAPI_MakeVertex(nurbsreg::test::to_gp(subset[i])),
                                    shape.shape);
                              } catch (const Standard_Failure&) {
                              }
                            }
                          });
      });
      row.occt_rate = n / (now() - t0);
    } catch (const std::exception&) {
    }
  }
  return row;
}

std::string rate(double r) {
  if (!std::isfinite(r)) return "–";
  char b[32];
  if (r >= 1e6) {
    std::snprintf(b, sizeof b, "%.2f M", r / 1e6);
  } else if (r >= 1e3) {
    std::snprintf(b, sizeof b, "%.0f k", r / 1e3);
  } else {
    std::snprintf(b, sizeof b, "%.0f", r);
  }
  return b;
}
std::string secs(double s) {
  if (!std::isfinite(s)) return "–";
  char b[32];
  std::snprintf(b, sizeof b, s < 0.1 ? "%.3f" : "%.2f", s);
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  CLI::App app{"Every real CAD model: load, prepare, project, align; nurbsreg and OpenCASCADE"};
  app.add_option("--models", opt.models, "substrings of the model names (default: all)")
      ->delimiter(',');
  app.add_option("--points", opt.points, "points per projection run and alignment");
  app.add_option("--occt-points", opt.occt_points, "mixed points through OpenCASCADE (0: none)");
  app.add_option("--occt-max-faces", opt.occt_max_faces, "OCCT only on models with fewer faces");
  app.add_option("--threads", opt.threads);
  app.add_option("--repeat", opt.repeat, "runs per projection measurement (the fastest kept)");
  app.add_flag("--skip-align", opt.skip_align);
  bool verbose = false;
  app.add_flag("-v,--verbose", verbose, "the alignment's passes (their certificates and searches)");
  app.add_option("--data", opt.data, "shared/data/real");
  CLI11_PARSE(app, argc, argv);
  if (verbose) spdlog::set_level(spdlog::level::debug);

  const std::string cache_dir = (std::filesystem::temp_directory_path() /
                                 ("nurbsreg_bench_cache_" + std::to_string(::getpid())))
                                    .string();
  std::vector<Row> rows;
  bool agree = true;
  for (const ModelFile& f : all_models(opt.data, opt.examples)) {
    if (!opt.models.empty() &&
        std::none_of(opt.models.begin(), opt.models.end(),
                     [&](const std::string& m) { return f.name.find(m) != std::string::npos; }))
      continue;
    std::fprintf(stderr, "%s ...\n", f.name.c_str());
    rows.push_back(run_model(f, opt, cache_dir));
    agree = agree && rows.back().threads_agree;
  }
  std::filesystem::remove_all(cache_dir);

  std::printf(
      "\n%zu points per run, %d threads, fastest of %d alternating runs.\n\n| model | faces | "
      "patches (trim-straddling, rational, max deg) | edge pieces | diagonal (control pts) | "
      "convert s | from cache s | prepare s | bounds s | peak MB | near pts/s (per CPU-s) | "
      "mixed pts/s (per CPU-s) | align wall s, CPU s (iters, rms) | OCCT DSS pts/s | near, "
      "mixed pts/s with a search per point (chain_cold off) | near, mixed proven by near lists "
      "|\n| --- | "
      "---: | --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | "
      "---: | ---: |\n",
      opt.points, opt.threads, opt.repeat);
  for (const Row& r : rows) {
    if (!r.error.empty()) {
      std::printf("| %s | error: %s |\n", r.file.name.c_str(), r.error.c_str());
      continue;
    }
    char align[96] = "–";
    if (std::isfinite(r.align_s))
      std::snprintf(align, sizeof align, "%s, %s (%d, %.2g%s)", secs(r.align_s).c_str(),
                    secs(r.align_cpu_s).c_str(), r.align_iterations, r.align_rms,
                    r.align_converged ? "" : ", not converged");
    std::printf(
        "| %s | %zu | %zu (%zu, %zu, %d) | %zu | %.4g %s (%.4g) | %s | %s | %s | %s | %.0f | %s "
        "(%s) | "
        "%s (%s) | %s | %s | %s, %s | %.1f%%, %.1f%% |\n",
        r.file.name.c_str(), r.faces, r.patches, r.boundary_patches, r.rational_patches,
        r.max_degree, r.edge_pieces, r.diagonal, r.bounds_kind.c_str(), r.control_diagonal,
        secs(r.convert_s).c_str(), secs(r.cache_s).c_str(), secs(r.prepare_s).c_str(),
        secs(r.bounds_s).c_str(), r.memory_mb, rate(r.near_rate).c_str(),
        rate(r.near_cpu_rate).c_str(), rate(r.mixed_rate).c_str(), rate(r.mixed_cpu_rate).c_str(),
        align, rate(r.occt_rate).c_str(), rate(r.near_separate_rate).c_str(),
        rate(r.mixed_separate_rate).c_str(), 100.0 * r.near_listed, 100.0 * r.mixed_listed);
  }
  std::printf(
      "\nPer point (near | mixed | last ICP pass): hierarchy items clipped (patches + trim-edge "
      "pieces), of the patches those clipped against their trim region and the rational ones, "
      "sub-patch splits, Newton iterations, trimmed sub-patches dropped and candidates rejected "
      "as outside the region; ICP: answers proven by warm certificates.\n\n| model | items | "
      "patches | trimmed | rational | edge pieces | splits | Newton | region drops | region "
      "rejections | ICP certified |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- "
      "| ---: |\n");
  for (const Row& r : rows) {
    if (!r.error.empty()) continue;
    const auto three = [&](double Profile::*f) {
      char b[64];
      std::snprintf(b, sizeof b, "%.1f / %.1f / %.1f", r.near.*f, r.mixed.*f, r.warm.*f);
      return std::string(b);
    };
    std::printf("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %.3f |\n", r.file.name.c_str(),
                three(&Profile::items).c_str(), three(&Profile::patches).c_str(),
                three(&Profile::trimmed).c_str(), three(&Profile::rational).c_str(),
                three(&Profile::edges).c_str(), three(&Profile::subdivisions).c_str(),
                three(&Profile::newton).c_str(), three(&Profile::region_drops).c_str(),
                three(&Profile::region_rejections).c_str(), r.warm.certified);
  }
  if (!agree) std::printf("\nERROR: 1 and 2 threads disagree on some model\n");
  return agree ? 0 : 1;
}
