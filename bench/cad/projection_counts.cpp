// projection_counts: a small, deterministic run of one model for instruction counts (callgrind)
// on a shared machine (issue 26): load a JSON model (e.g. from `nurbsreg convert`), prepare it,
// project N near points (a synthetic scan, noise 0.5% of the trimmed diagonal or --noise) and N
// mixed points (half near, half anywhere in the box enlarged by 10% of its diagonal; the same
// recipe and seeds as real_models_bench), optionally align an --align-point scan (3 degrees and 2%
// of the diagonal off). Prints load / prepare CPU seconds, the per-point counters and a checksum of
// every answer (status, distance, entity, u, v bit for bit), so that a change can be shown not
// to move a single result. See bench/README.md, "Real CAD models" (issue 26).
//
//   valgrind --tool=callgrind --collect-atstart=no
//       --toggle-collect='nurbsreg::engine::Projector::project(*'
//       build/bench/cad/projection_counts model.json --points 2000 --sets near   (one line)

#include <spdlog/spdlog.h>
#include <tbb/task_arena.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/io/model_json.hpp"

namespace engine = nurbsreg::engine;
namespace io = nurbsreg::io;
namespace icp = nurbsreg::icp;
using engine::Vec3;

namespace {

double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// FNV-1a over the answers' bytes.
struct Checksum {
  std::uint64_t h = 1469598103934665603ull;
  void add(const void* data, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < n; ++i)
      h = (h ^ b[i]) * 1099511628211ull;
  }
  void add_double(double x) { add(&x, sizeof x); }
};

std::uint64_t checksum(const engine::ProjectionResults& r, std::size_t n) {
  Checksum c;
  for (std::size_t i = 0; i < n; ++i) {
    c.add(&r.status[i], sizeof r.status[i]);
    c.add(&r.entity[i], sizeof r.entity[i]);
    c.add_double(r.distance[i]);
    c.add_double(r.u[i]);
    c.add_double(r.v[i]);
  }
  return c.h;
}

void print_counters(const char* what, const engine::ProjectionCounters& c) {
  const double n = std::max<double>(1.0, static_cast<double>(c.points - c.skipped));
  std::printf(
      "%s: items %.2f edges %.2f trimmed %.2f rational %.2f splits %.2f newton %.2f drops %.2f "
      "rejections %.2f certified %.3f listed %.3f lists %.3f\n",
      what, c.patches_visited / n, c.edge_pieces_visited / n, c.trimmed_patches_visited / n,
      c.rational_patches_visited / n, c.subdivisions / n, c.newton_iterations / n,
      c.region_drops / n, c.region_rejections / n, (c.certified + c.reach_proven) / n, c.listed / n,
      c.lists_made / n);
}

// Where the certifying frame's answers lie and which of them got a certificate: a foot on a
// trim edge, or on a rational / polynomial patch of a trimmed / untrimmed face (why a warm
// point is not certified: no certificate can be made there, or the proof failed).
void print_certificate_kinds(const engine::PreparedModel& model, const engine::ProjectionResults& r,
                             std::size_t n) {
  enum { kEdge, kTrimRational, kTrimPoly, kRational, kPoly, kKinds };
  const char* names[kKinds] = {"trim edge", "trimmed rational", "trimmed polynomial",
                               "untrimmed rational", "untrimmed polynomial"};
  std::size_t count[kKinds] = {}, made[kKinds] = {};
  for (std::size_t i = 0; i < n; ++i) {
    if (r.status[i] != engine::ProjectionStatus::ok) continue;
    int kind = kEdge;
    if (!r.on_trim_edge[i]) {
      const std::int64_t k = model.locate_patch(r.entity[i], r.u[i], r.v[i]);
      const bool rational = k >= 0 && model.patch(static_cast<std::size_t>(k)).rational;
      const bool trimmed = model.surface_region(r.entity[i]) != nullptr;
      kind = trimmed ? (rational ? kTrimRational : kTrimPoly) : (rational ? kRational : kPoly);
    }
    ++count[kind];
    made[kind] += r.certificate.empty() ? 0 : r.certificate[i].radius > 0.0f;
  }
  std::printf("feet:");
  for (int k = 0; k < kKinds; ++k) {
    std::printf(" %s %.3f (certified %.3f)%s", names[k], double(count[k]) / n, double(made[k]) / n,
                k + 1 < kKinds ? "," : "\n");
  }
}

// The hinted frame of the warm set, on its own so that callgrind can count it alone
// (--toggle-collect='*warm_frame*': callgrind_counts.sh).
[[gnu::noinline]] void warm_frame(engine::Projector& projector, const std::vector<Vec3>& points,
                                  const std::vector<engine::ProjectionHint>& hints,
                                  engine::ProjectionResults& out,
                                  engine::ProjectionCounters& counters) {
  projector.project(engine::PointView::of(points), {}, out, hints, &counters);
}

// --check: the finder's answers in every pass of the alignment against a cold projection of the
// same points (no hints, no certificates): the warm starts, borrowed certificates and the
// finder's per-point state may change which Newton start finds a foot, never its distance.
class CheckedFinder final : public icp::CorrespondenceFinder {
 public:
  CheckedFinder(icp::ModelCorrespondenceFinder& finder, const engine::PreparedModel& model)
      : finder_(finder), cold_(model), diagonal_(model.geometry_bounds().box.diagonal()) {}
  void reset(std::size_t scan_size) override { finder_.reset(scan_size); }
  void find(const icp::CorrespondenceQuery& query, std::span<icp::Correspondence> out) override {
    finder_.find(query, out);
    engine::ProjectionOptions options;
    options.max_distance = query.max_distance;
    cold_.project(engine::PointView::of(query.points), options, cold_results_);
    const engine::ProjectionResults& warm = finder_.last_results();
    for (std::size_t k = 0; k < out.size(); ++k) {
      ++answers_;
      const bool cold_ok = cold_results_.status[k] == engine::ProjectionStatus::ok;
      if (out[k].valid != cold_ok) {
        ++wrong_;
        continue;
      }
      if (!cold_ok) continue;
      const double d = out[k].distance - cold_results_.distance[k];
      warm_farther_ = std::max(warm_farther_, d);
      if (-d > cold_farther_) {
        cold_farther_ = -d;
        worst_ = {query.points[k],
                  warm.entity[k],
                  cold_results_.entity[k],
                  warm.u[k],
                  warm.v[k],
                  cold_results_.u[k],
                  cold_results_.v[k],
                  warm.on_trim_edge[k] != 0,
                  cold_results_.on_trim_edge[k] != 0,
                  out[k].distance,
                  cold_results_.distance[k]};
      }
      if (std::abs(d) > 1e-10 * diagonal_) ++wrong_;
      if (warm.entity[k] != cold_results_.entity[k]) ++other_face_;
    }
  }
  void print() const {
    std::printf(
        "check: %zu answers, %zu not the cold distance (1e-10 of the diagonal); farther "
        "than the cold foot by up to %.3g, nearer by up to %.3g of the diagonal; %zu on "
        "another face than the cold foot\n",
        answers_, wrong_, warm_farther_ / diagonal_, cold_farther_ / diagonal_, other_face_);
    if (cold_farther_ > 0.0) {
      // The point where the cold answer is farthest above the finder's, exactly (hex), to
      // reproduce it in a test.
      const Worst& w = worst_;
      std::printf(
          "check: worst cold point %a %a %a: finder face %d (%a, %a)%s distance %.17g, cold "
          "face %d (%a, %a)%s distance %.17g\n",
          w.p.x(), w.p.y(), w.p.z(), w.warm_entity, w.warm_u, w.warm_v,
          w.warm_edge ? " on a trim edge," : ",", w.warm_distance, w.cold_entity, w.cold_u,
          w.cold_v, w.cold_edge ? " on a trim edge," : ",", w.cold_distance);
    }
  }

 private:
  icp::ModelCorrespondenceFinder& finder_;
  engine::Projector cold_;
  engine::ProjectionResults cold_results_;
  double diagonal_;
  std::size_t answers_ = 0, wrong_ = 0, other_face_ = 0;
  double warm_farther_ = 0.0, cold_farther_ = 0.0;
  struct Worst {
    Vec3 p = Vec3::Zero();
    int warm_entity = -1, cold_entity = -1;
    double warm_u = 0, warm_v = 0, cold_u = 0, cold_v = 0;
    bool warm_edge = false, cold_edge = false;
    double warm_distance = 0, cold_distance = 0;
  } worst_;
};

// The alignment alone, so that callgrind can count all of it (the finder's hints and atlas
// lookups too, which lie outside Projector::project): --toggle-collect='*align_scan*'.
[[gnu::noinline]] icp::IcpResult align_scan(icp::CorrespondenceFinder& finder,
                                            const std::vector<Vec3>& scan) {
  icp::IcpSolver solver;
  return solver.align(finder, scan, Eigen::Isometry3d::Identity());
}

}  // namespace

int main(int argc, char** argv) {
  std::string path;
  std::size_t points = 2000, align_points = 0;
  int threads = 1;
  std::string sets = "near,mixed";
  CLI::App app{"One model: prepare, project near and mixed points, align (instruction counts)"};
  app.add_option("model", path, "a JSON model (nurbsreg convert)")->required();
  app.add_option("--points", points, "near and mixed points");
  app.add_option("--align", align_points, "points of an alignment (0: none)");
  app.add_option("--threads", threads);
  app.add_option("--sets", sets,
                 "which point sets to project: near, mixed, warm (comma-separated)");
  bool check = false;
  app.add_flag("--check", check,
               "compare every pass of the alignment with a cold projection (CheckedFinder)");
  std::string save_json;
  app.add_option("--save-json", save_json,
                 "write the loaded model as JSON (a STEP/IGES file converted once, for the "
                 "callgrind runs) and exit");
  bool verbose = false;
  app.add_flag("-v,--verbose", verbose, "log every ICP pass (the finder's debug lines)");
  double noise = 0.005;
  bool no_chain = false;
  app.add_flag("--no-chain", no_chain,
               "near and mixed: a separate search per point (ProjectionOptions::chain_cold off)");
  app.add_option("--noise", noise, "the near points' noise, a fraction of the trimmed diagonal")
      ->check(CLI::NonNegativeNumber);
  engine::ProjectionOptions certify;
  certify.certify = true;
  app.add_option("--certificate-radius", certify.certificate_radius,
                 "the warm set's certificate radius cap (model units; 0: the engine's default)");
  app.add_option("--certificate-span", certify.certificate_span,
                 "the warm set's ProjectionOptions::certificate_span")
      ->check(CLI::Range(1, engine::kMaxCertificateSpan));
  CLI11_PARSE(app, argc, argv);
  if (verbose) spdlog::set_level(spdlog::level::debug);

  tbb::task_arena arena(threads);
  double c = cpu_seconds();
  io::ModelFileOptions no_cache;
  no_cache.cache.enabled = false;
  const engine::Model model = io::read_model_file(path, no_cache);
  const double load_s = cpu_seconds() - c;
  if (!save_json.empty()) {
    io::write_model(save_json, model);
    return 0;
  }
  c = cpu_seconds();
  const auto wall = std::chrono::steady_clock::now();
  // Inside the arena: the preparation's parallel parts run on --threads threads too.
  std::optional<engine::PreparedModel> prepared_storage;
  arena.execute([&] { prepared_storage.emplace(model); });
  const engine::PreparedModel& prepared = *prepared_storage;
  const double prepare_s = cpu_seconds() - c;
  const double prepare_wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall).count();
  c = cpu_seconds();
  const engine::ModelBounds& bounds = prepared.geometry_bounds();
  const double bounds_s = cpu_seconds() - c;
  std::printf("%s: load %.3f s, prepare %.3f s (wall %.3f s), bounds %.3f s (CPU)\n", path.c_str(),
              load_s, prepare_s, prepare_wall, bounds_s);
  const double diagonal = bounds.box.diagonal();

  engine::SyntheticScanOptions synth;
  synth.points = points;
  synth.noise_sigma = noise * diagonal;
  synth.seed = 26;
  const std::vector<Vec3> near = engine::make_synthetic_scan(model, synth).points;
  const std::vector<Vec3>& near_ref = near;
  std::vector<Vec3> mixed(near.begin(),
                          near.begin() + static_cast<std::ptrdiff_t>(near.size() / 2));
  {
    std::mt19937_64 rng(2026);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const Vec3 margin = Vec3::Constant(0.1 * diagonal);
    const Vec3 lo = bounds.box.lo - margin, extent = bounds.box.hi + margin - lo;
    while (mixed.size() < near.size())
      mixed.push_back(lo + Vec3(u(rng) * extent.x(), u(rng) * extent.y(), u(rng) * extent.z()));
  }
  for (const auto& [name, pts] :
       {std::pair{"near", &near_ref}, std::pair{"mixed", &std::as_const(mixed)}}) {
    if (sets.find(name) == std::string::npos) continue;
    engine::ProjectionResults out;
    engine::ProjectionCounters counters;
    c = cpu_seconds();
    arena.execute([&] {
      engine::Projector projector(prepared);
      engine::ProjectionOptions cold;
      cold.chain_cold = !no_chain;
      projector.project(engine::PointView::of(*pts), cold, out, {}, &counters);
    });
    const double s = cpu_seconds() - c;
    std::printf("%s: %zu points, %.0f pts per CPU-s, checksum %016llx\n", name, pts->size(),
                pts->size() / s, static_cast<unsigned long long>(checksum(out, pts->size())));
    print_counters(name, counters);
  }
  if (sets.find("warm") != std::string::npos) {
    // A tracking frame: the near points certified (a frame made with certify), then the same
    // points moved by 1e-4 of the diagonal, hinted by the first frame's answers.
    engine::ProjectionResults first, out;
    engine::ProjectionCounters made, counters;
    std::vector<Vec3> moved(near);
    std::mt19937_64 rng(28);
    std::normal_distribution<double> g(0.0, 1e-4 * diagonal / std::sqrt(3.0));
    for (Vec3& q : moved)
      q += Vec3(g(rng), g(rng), g(rng));
    arena.execute([&] {
      engine::Projector projector(prepared);
      projector.project(engine::PointView::of(near), certify, first, {}, &made);
      std::vector<engine::ProjectionHint> hints(near.size());
      for (std::size_t i = 0; i < near.size(); ++i)
        hints[i] = first.hint(i);
      c = cpu_seconds();
      warm_frame(projector, moved, hints, out, counters);
    });
    const double s = cpu_seconds() - c;
    print_certificate_kinds(prepared, first, moved.size());
    std::printf(
        "warm: %zu points, %.0f pts per CPU-s, certificates made %.3f per point, checksum "
        "%016llx\n",
        moved.size(), moved.size() / s, double(made.certificates_made) / moved.size(),
        static_cast<unsigned long long>(checksum(out, moved.size())));
    print_counters("warm", counters);
  }
  if (align_points > 0) {
    engine::SyntheticScanOptions scan = synth;
    scan.points = align_points;
    scan.seed = 27;
    const double d = 0.02 * diagonal / std::sqrt(3.0);
    scan.T_scan_model = engine::pose_from_euler_degrees(2.0, 1.5, 1.5, Vec3(d, d, d));
    const engine::SyntheticScan s = engine::make_synthetic_scan(model, scan);
    arena.execute([&] {
      icp::ModelCorrespondenceFinder finder(prepared);
      c = cpu_seconds();
      std::optional<CheckedFinder> checked;
      if (check) checked.emplace(finder, prepared);
      const icp::IcpResult result =
          checked ? align_scan(*checked, s.points) : align_scan(finder, s.points);
      const double t = cpu_seconds() - c;
      if (checked) checked->print();
      Checksum pose;
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
          pose.add_double(result.T_model_scan.matrix()(i, j));
      std::printf("align: %zu points, %.3f CPU s, %d iterations, rms %.6g, pose checksum %016llx\n",
                  align_points, t, result.iterations, result.rms,
                  static_cast<unsigned long long>(pose.h));
      // The pose itself, to measure how far two builds' poses lie apart when their checksums
      // differ (rotation rows, then the translation).
      const Eigen::Matrix4d& m = result.T_model_scan.matrix();
      std::printf("pose:");
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j)
          std::printf(" %.17g", m(i, j));
      // Its standard deviations (IcpResult::covariance: rotation, then translation).
      std::printf("\nsigma:");
      for (int i = 0; i < 6; ++i)
        std::printf(" %.6g", std::sqrt(std::max(0.0, result.covariance(i, i))));
      std::printf("\n");
      print_counters("last ICP pass", finder.last_counters());
    });
  }
  return 0;
}
