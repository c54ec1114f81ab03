// libFuzzer harness: JSON models (parse_model). An accepted model must also be one the engine
// can stand behind: it is prepared and two points are projected, whose distances must be finite
// (a model near 1e150 once gave NaN rows with exit 0). The Bézier limit is lowered so that one
// input stays fast.
#include <cmath>
#include <cstdlib>
#include <string_view>
#include <vector>

#include "fuzz_support.hpp"
#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/io/model_json.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  setenv("NURBSREG_MAX_BEZIER_POINTS", "20000", 1);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace nurbsreg;
  const std::string label = "model.json";
  engine::Model model;
  try {
    model = io::parse_model(std::string_view(reinterpret_cast<const char*>(data), size), label);
  } catch (const io::InputError& e) {
    fuzz::check_message(e, label);
    return 0;
  }
  std::vector<engine::Vec3> points = {{0, 0, 0}};
  if (!model.surfaces.empty()) points.push_back(model.surfaces[0].control_points[0] * 1.5);
  if (!model.curves.empty()) points.push_back(model.curves[0].control_points[0] * 1.5);
  const engine::PreparedModel prepared(std::move(model));
  engine::Projector projector(prepared);
  engine::ProjectionResults results;
  const engine::ProjectionTarget target = prepared.model().surfaces.empty()
                                              ? engine::ProjectionTarget::curves
                                              : engine::ProjectionTarget::surfaces;
  engine::ProjectionOptions options;
  options.target = target;
  projector.project_serial(engine::PointView::of(points), options, results);
  for (std::size_t i = 0; i < results.size(); ++i) {
    if (results.status[i] == engine::ProjectionStatus::ok && !std::isfinite(results.distance[i])) {
      std::fprintf(stderr, "non-finite distance for point %zu\n", i);
      std::abort();
    }
  }
  return 0;
}
