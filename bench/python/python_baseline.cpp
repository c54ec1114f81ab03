// The C++ side of bench/python/bench_python.py: projects the points of a file with the C++ API
// (engine::Projector::project, one prepared model and one Projector as nurbsreg.project keeps)
// `repeats` times and prints the seconds of each call as one JSON line, for fresh result arrays
// per call (what every nurbsreg.project call gets: the arrays become the caller's) and for
// results reused across calls (the C++ API's frame-after-frame use); with the process's CPU
// seconds of each call beside them (all threads: less disturbed by a loaded machine than wall
// time).
//
//   build/bench/python/python_baseline MODEL POINTS REPEATS

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/io/point_cloud.hpp"

namespace {

using namespace nurbsreg;

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// CPU time of the whole process (every thread), as Python's time.process_time().
double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

std::string json_list(const std::vector<double>& values) {
  std::string text = "[";
  for (std::size_t i = 0; i < values.size(); ++i)
    text += (i ? ", " : "") + std::to_string(values[i]);
  return text + "]";
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s MODEL POINTS REPEATS\n", argv[0]);
    return 2;
  }
  const engine::PreparedModel model(io::read_model_file(argv[1]));
  const io::PointCloud cloud = io::read_point_cloud(argv[2]);
  const int repeats = std::atoi(argv[3]);
  engine::Projector projector(model);
  const engine::PointView points = engine::PointView::of(cloud.points);
  {
    engine::ProjectionResults warm_up;  // the Projector's per-thread scratch, as Python's pool
    projector.project(points, {}, warm_up);
  }
  std::vector<double> fresh, reused, fresh_cpu, reused_cpu;
  engine::ProjectionResults kept;
  for (int k = 0; k < repeats; ++k) {
    {
      const auto start = std::chrono::steady_clock::now();
      const double cpu = cpu_seconds();
      engine::ProjectionResults results;
      projector.project(points, {}, results);
      fresh.push_back(seconds_since(start));
      fresh_cpu.push_back(cpu_seconds() - cpu);
    }
    const auto start = std::chrono::steady_clock::now();
    const double cpu = cpu_seconds();
    projector.project(points, {}, kept);
    reused.push_back(seconds_since(start));
    reused_cpu.push_back(cpu_seconds() - cpu);
  }
  std::printf(
      "{\"points\": %zu, \"fresh\": %s, \"reused\": %s, \"fresh_cpu\": %s, \"reused_cpu\": "
      "%s}\n",
      cloud.size(), json_list(fresh).c_str(), json_list(reused).c_str(),
      json_list(fresh_cpu).c_str(), json_list(reused_cpu).c_str());
  return 0;
}
