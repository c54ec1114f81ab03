#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::engine {
namespace {

std::string entity_label(const char* kind, std::size_t index, const std::string& name) {
  std::string label = std::string(kind) + " " + std::to_string(index);
  if (!name.empty()) label += " \"" + name + "\"";
  return label;
}

}  // namespace

std::optional<std::string> Model::validate() const {
  if (surfaces.empty() && curves.empty()) {
    return std::string("model: has no surfaces and no curves (at least one is required)");
  }
  for (std::size_t i = 0; i < surfaces.size(); ++i) {
    if (auto e = surfaces[i].validate()) {
      return entity_label("surface", i, surfaces[i].name) + ": " + *e;
    }
  }
  for (std::size_t i = 0; i < curves.size(); ++i) {
    if (auto e = curves[i].validate()) return entity_label("curve", i, curves[i].name) + ": " + *e;
  }
  return std::nullopt;
}

}  // namespace nurbsreg::engine
