// Frame after frame (tracking, inspection lines): each frame's results are the next frame's
// hints, read in place, and carry warm certificates, so a point that moved a little is answered
// by one Newton on one patch instead of a search. The answers stay exact: the last frame is
// compared with a cold projection of the same points.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <vector>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/io/model_file.hpp"
using namespace nurbsreg;

int main(int argc, char** argv) try {
  const char* file = argc > 1 ? argv[1] : "examples/panel.json";
  const engine::Model cad = io::read_model_file(file);
  engine::SyntheticScanOptions synth;  // 20,000 points up to ~1 mm off the surfaces
  synth.points = 20000;
  synth.noise_sigma = 0.3;
  std::vector<engine::Vec3> frame = engine::make_synthetic_scan(cad, synth).points;

  const engine::PreparedModel model(cad);
  engine::Projector projector(model);
  engine::ProjectionOptions options;
  options.certify = true;  // every answer also gets a certificate for the next frame
  engine::ProjectionResults results;
  // The previous frame's answers as this frame's hints, without a copy.
  const engine::HintView previous(&results, frame.size(), [](const void* r, std::size_t i) {
    return static_cast<const engine::ProjectionResults*>(r)->hint(i);
  });
  for (int f = 0; f < 5; ++f) {
    for (engine::Vec3& p : frame)
      p += engine::Vec3(0.002, -0.001, 0.001);  // a slow drift
    engine::ProjectionCounters counters;
    projector.project(engine::PointView::of(frame), options, results,
                      f == 0 ? engine::HintView{} : previous, &counters);
    std::printf("frame %d: %llu points, %llu proven by their hint's certificate\n", f,
                static_cast<unsigned long long>(counters.points),
                static_cast<unsigned long long>(counters.certified));
  }

  engine::ProjectionResults cold;
  projector.project(engine::PointView::of(frame), {}, cold);
  double largest = 0.0;
  for (std::size_t i = 0; i < frame.size(); ++i)
    largest = std::max(largest, std::abs(results.distance[i] - cold.distance[i]));
  std::printf("largest distance difference from a cold projection: %.3g mm\n", largest);
} catch (const std::exception& e) {
  std::fprintf(stderr, "error: %s\n", e.what());
  return 3;
}
