// The C++ side of bench/python/bench_python.py: projects the points of a file with the C++ API
// (engine::Projector::project, one prepared model and one Projector as nurbsreg.project keeps)
// `repeats` times and prints the seconds of each call as one JSON line, for fresh result arrays
// per call (what every nurbsreg.project call gets: the arrays become the caller's) and for
// results reused across calls (the C++ API's frame-after-frame use).
//
//   build/bench/python/python_baseline MODEL POINTS REPEATS

#include <chrono>
#include <cstdio>
#include <cstdlib>
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
  std::vector<double> fresh, reused;
  engine::ProjectionResults kept;
  for (int k = 0; k < repeats; ++k) {
    {
      const auto start = std::chrono::steady_clock::now();
      engine::ProjectionResults results;
      projector.project(points, {}, results);
      fresh.push_back(seconds_since(start));
    }
    const auto start = std::chrono::steady_clock::now();
    projector.project(points, {}, kept);
    reused.push_back(seconds_since(start));
  }
  std::printf("{\"points\": %zu, \"fresh\": %s, \"reused\": %s}\n", cloud.size(),
              json_list(fresh).c_str(), json_list(reused).c_str());
  return 0;
}
