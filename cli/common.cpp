#include "common.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "nurbsreg/io/model_file.hpp"

namespace nurbsreg::cli {
namespace {

// Faces that were left out, or are only partly in the model, change every answer near them:
// every command that loads the model says so (`info` lists the details).
void warn_about_import(const std::string& path, const engine::Model& model,
                       const io::CadImportReport& report) {
  if (!model.skipped_faces.empty()) {
    const engine::SkippedFace& first = model.skipped_faces.front();
    spdlog::warn(
        "{}: {} of {} faces could not be converted and are not in the model (face {}: {}{})", path,
        model.skipped_faces.size(), report.faces, first.face, first.reason,
        model.skipped_faces.size() > 1 ? "; `nurbsreg info` lists the others" : "");
  }
  // Curves beyond the domain by a sliver (CAD tolerances) cost a sliver of the face; above 1e-4
  // of the domain the missing part is worth a warning.
  constexpr double kNoticeable = 1e-4;
  std::vector<io::CadImportReport::FaceBeyondDomain> faces;
  for (const auto& f : report.faces_beyond_domain) {
    if (f.excursion > kNoticeable) faces.push_back(f);
  }
  if (faces.empty()) return;
  std::sort(faces.begin(), faces.end(),
            [](const auto& a, const auto& b) { return a.excursion > b.excursion; });
  std::string list;
  constexpr std::size_t kListed = 5;
  for (std::size_t k = 0; k < std::min(faces.size(), kListed); ++k) {
    list += fmt::format("{}face {} by {:.2g}%", k ? ", " : "", faces[k].face,
                        100.0 * faces[k].excursion);
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

engine::Model load_model_file(const std::string& path) {
  io::CadImportReport report;
  engine::Model model = io::read_model_file(path, &report);
  warn_about_import(path, model, report);
  return model;
}

}  // namespace nurbsreg::cli
