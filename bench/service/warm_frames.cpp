// Warm session frames without the HTTP layer: what `nurbsreg serve` computes for a session's
// frames (registration::Aligner with the model's shared coarse-stage features, each frame from
// the previous frame's pose), frame by frame, with each frame's wall and process CPU time and its
// ICP iterations. The first file is aligned from any pose (a session's first frame), then
// `--frames` frames cycle through the files (the first one included) from the pose before.
// Under callgrind (`--callgrind`, run with --collect-atstart=no) only the warm frames are
// measured.
//
//   build/bench/service/warm_frames MODEL FRAMES SCAN... [--threads N] [--callgrind] [-v]
//                                   [--fresh-certificates] [--no-coarse]
//
// -v: the ICP iterations and each correspondence pass (engine counters) as debug lines.
// --fresh-certificates: every frame starts without the certificates of the frames before (as
// `align --init` in a new process; the service's sessions keep them).
// --no-coarse: the warm frames' ICP on all points from the first iteration (no subsample stages:
// IcpOptions::auto_coarse false), to weigh the 10% stage against the full passes it saves.

#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <valgrind/callgrind.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/registration/alignment.hpp"

namespace {

using namespace nurbsreg;

double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> scans;
  int threads = 0;
  bool callgrind = false;
  bool keep = true;
  bool coarse = true;
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--threads" && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else if (a == "--callgrind") {
      callgrind = true;
    } else if (a == "--fresh-certificates") {
      keep = false;
    } else if (a == "--no-coarse") {
      coarse = false;
    } else if (a == "-v") {
      spdlog::set_level(spdlog::level::debug);
    } else {
      scans.push_back(a);
    }
  }
  if (argc < 4 || scans.empty()) {
    std::fprintf(stderr,
                 "usage: %s MODEL FRAMES SCAN... [--threads N] [--callgrind] [-v] "
                 "[--fresh-certificates] [--no-coarse]\n",
                 argv[0]);
    return 2;
  }
  const int frames = std::atoi(argv[2]);
  std::optional<tbb::global_control> control;
  if (threads > 0) control.emplace(tbb::global_control::max_allowed_parallelism, threads);
  const engine::PreparedModel model(io::read_model_file(argv[1]));
  const registration::RegistrationOptions options;
  auto features =
      std::make_shared<const registration::ModelFeatures>(model, options.global.features);
  features->descriptors();
  std::vector<io::PointCloud> clouds;
  for (const std::string& s : scans)
    clouds.push_back(io::read_point_cloud(s));
  registration::Aligner aligner(model, icp::IcpOptions{}, options, features);
  aligner.keep_certificates(keep);
  registration::AlignmentResult first = aligner.align(clouds[0].points);
  // --no-coarse: a second aligner (it starts without the first frame's certificates).
  std::optional<registration::Aligner> full_only;
  if (!coarse) {
    icp::IcpOptions warm_options;
    warm_options.auto_coarse = false;
    full_only.emplace(model, warm_options, options, features);
    full_only->keep_certificates(keep);
  }
  registration::Aligner& warm = full_only ? *full_only : aligner;
  if (!first.ok()) {
    std::fprintf(stderr, "first frame: %s\n", first.failure->c_str());
    return 1;
  }
  Eigen::Isometry3d pose = first.icp.T_model_scan;
  double cpu_total = 0.0, wall_total = 0.0;
  if (callgrind) CALLGRIND_START_INSTRUMENTATION;
  for (int k = 0; k < frames; ++k) {
    const io::PointCloud& cloud = clouds[static_cast<std::size_t>(k) % clouds.size()];
    const double cpu0 = cpu_seconds();
    const auto wall0 = std::chrono::steady_clock::now();
    const registration::AlignmentResult r = warm.align(cloud.points, pose);
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    const double cpu = cpu_seconds() - cpu0;
    cpu_total += cpu;
    wall_total += wall;
    std::printf("frame %d: %.1f ms wall, %.1f ms CPU, %d iterations, rms %.6g, %s\n", k, 1e3 * wall,
                1e3 * cpu, r.icp.iterations, r.icp.rms, r.ok() ? "ok" : r.failure->c_str());
    if (r.ok()) pose = r.icp.T_model_scan;
  }
  if (callgrind) CALLGRIND_STOP_INSTRUMENTATION;
  std::printf("mean: %.1f ms wall, %.1f ms CPU per frame\n", 1e3 * wall_total / frames,
              1e3 * cpu_total / frames);
  return 0;
}
