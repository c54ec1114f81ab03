#include "common.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "nurbsreg/io/model_file.hpp"

namespace nurbsreg::cli {
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

// Faces that were left out, or are only partly in the model, change every answer near them:
// every command that loads the model says so (`info` lists the details).
void warn_about_missing_faces(const std::string& path, const engine::Model& model) {
  if (!model.skipped_faces.empty()) {
    const engine::SkippedFace& first = model.skipped_faces.front();
    spdlog::warn(
        "{}: {} of {} faces could not be converted and are not in the model (face {}: {}{})", path,
        model.skipped_faces.size(), model.skipped_faces.size() + model.surfaces.size(), first.face,
        first.reason, model.skipped_faces.size() > 1 ? "; `nurbsreg info` lists the others" : "");
  }
  // Curves beyond the domain by a sliver (CAD tolerances) cost a sliver of the face; above 1e-4
  // of the domain the missing part is worth a warning.
  constexpr double kNoticeable = 1e-4;
  std::vector<std::pair<double, const engine::NurbsSurface*>> faces;
  for (const engine::NurbsSurface& s : model.surfaces) {
    const double excursion = trim_excursion(s);
    if (excursion > kNoticeable) faces.emplace_back(excursion, &s);
  }
  if (faces.empty()) return;
  std::stable_sort(faces.begin(), faces.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::string list;
  constexpr std::size_t kListed = 5;
  for (std::size_t k = 0; k < std::min(faces.size(), kListed); ++k) {
    list += fmt::format("{}{} by {:.2g}%", k ? ", " : "", faces[k].second->name,
                        100.0 * faces[k].first);
  }
  if (faces.size() > kListed) list += ", ...";
  spdlog::warn(
      "{}: the trim loops of {} faces leave their surface's parameter domain ({} of its width): "
      "the parts of those faces beyond it are missing from the model, so points near them may "
      "get a farther closest point elsewhere",
      path, faces.size(), list);
}

}  // namespace

std::unique_ptr<tbb::global_control> limit_threads(int threads) {
  if (threads < 0) throw UsageError("--threads: must be >= 0 (0 = all hardware threads)");
  if (threads == 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                               static_cast<std::size_t>(threads));
}

namespace {
bool model_cache_disabled = false;  // the application's --no-cache, set before any load
}  // namespace

void disable_model_cache() {
  model_cache_disabled = true;
}

engine::Model load_model_file(const std::string& path) {
  io::ModelFileOptions options;
  if (model_cache_disabled) options.cache.enabled = false;
  engine::Model model = io::read_model_file(path, options);
  warn_about_missing_faces(path, model);
  return model;
}

}  // namespace nurbsreg::cli
