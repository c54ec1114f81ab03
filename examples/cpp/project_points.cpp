// Exact closest points on a model: foot, distance and (u, v) for every point of a frame.
#include <cstdio>
#include <exception>
#include <vector>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/io/model_file.hpp"
using namespace nurbsreg;

int main(int argc, char** argv) try {
  const char* file = argc > 1 ? argv[1] : "examples/panel.json";  // JSON, STEP or IGES
  engine::PreparedModel model(io::read_model_file(file));         // decompose + cache, once
  engine::Projector projector(model);                             // reusable, per-thread scratch
  std::vector<engine::Vec3> points = {{10, 20, 5}, {50, 50, 30}};
  engine::ProjectionResults r;                              // structure of arrays
  projector.project(engine::PointView::of(points), {}, r);  // exact, parallel
  for (std::size_t i = 0; i < points.size(); ++i)
    std::printf("%zu: d = %.9f on surface %d at (u, v) = (%.6f, %.6f)\n", i, r.distance[i],
                r.entity[i], r.u[i], r.v[i]);
} catch (const std::exception& e) {
  std::fprintf(stderr, "error: %s\n", e.what());
  return 3;
}
