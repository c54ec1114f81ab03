#include "nurbsreg/io/model_warnings.hpp"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <utility>

namespace nurbsreg::io {
namespace {

// How far a face's trim curves leave its surface's parameter domain, as a fraction of the
// domain's width (0: not at all): the engine's face is the loops' region within the domain, so
// that part of the face is missing. 33 points per curve (a rational curve's control polygon
// overshoots the curve).
double trim_excursion(const engine::NurbsSurface& s) {
  const engine::ParamInterval du = s.domain_u(), dv = s.domain_v();
  double worst = 0.0;
  for (const engine::TrimLoop& loop : s.trim_loops) {
    for (const engine::TrimCurve& curve : loop.curves) {
      const engine::ParamInterval d = curve.uv.domain();
      for (int k = 0; k <= 32; ++k) {
        const engine::Vec3 p = curve.uv.evaluate(d.lo + (d.hi - d.lo) * k / 32);
        worst = std::max({worst, (du.lo - p.x()) / du.width(), (p.x() - du.hi) / du.width(),
                          (dv.lo - p.y()) / dv.width(), (p.y() - dv.hi) / dv.width()});
      }
    }
  }
  return worst;
}

}  // namespace

std::vector<std::string> model_warnings(const std::string& label, const engine::Model& model) {
  std::vector<std::string> warnings;
  if (!model.skipped_faces.empty()) {
    const engine::SkippedFace& first = model.skipped_faces.front();
    warnings.push_back(fmt::format(
        "{}: {} of {} faces could not be converted and are not in the model (face {}: {}{})", label,
        model.skipped_faces.size(), model.skipped_faces.size() + model.surfaces.size(), first.face,
        first.reason, model.skipped_faces.size() > 1 ? "; `nurbsreg info` lists the others" : ""));
  }
  // Curves beyond the domain by a sliver (CAD tolerances) cost a sliver of the face; above 1e-4
  // of the domain the missing part is worth a warning.
  constexpr double kNoticeable = 1e-4;
  std::vector<std::pair<double, const engine::NurbsSurface*>> faces;
  for (const engine::NurbsSurface& s : model.surfaces) {
    const double excursion = trim_excursion(s);
    if (excursion > kNoticeable) faces.emplace_back(excursion, &s);
  }
  if (faces.empty()) return warnings;
  std::stable_sort(faces.begin(), faces.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::string list;
  constexpr std::size_t kListed = 5;
  for (std::size_t k = 0; k < std::min(faces.size(), kListed); ++k) {
    list += fmt::format("{}{} by {:.2g}%", k ? ", " : "", faces[k].second->name,
                        100.0 * faces[k].first);
  }
  if (faces.size() > kListed) list += ", ...";
  warnings.push_back(fmt::format(
      "{}: the trim loops of {} faces leave their surface's parameter domain ({} of its width): "
      "the parts of those faces beyond it are missing from the model, so points near them may "
      "get a farther closest point elsewhere",
      label, faces.size(), list));
  return warnings;
}

}  // namespace nurbsreg::io
