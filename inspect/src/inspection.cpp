#include "nurbsreg/inspect/inspection.hpp"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>
#include <tbb/parallel_invoke.h>

#include <chrono>

#include "nurbsreg/inspect/deviation_ply.hpp"
#include "nurbsreg/inspect/html_report.hpp"
#include "nurbsreg/inspect/tessellation.hpp"
#include "nurbsreg/inspect/viewer_subset.hpp"
#include "nurbsreg/io/atomic_file.hpp"

namespace nurbsreg::inspect {
namespace {

void write_text(const std::string& path, const std::string& text) {
  io::write_atomically(path, [&](std::ostream& out) {
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
  });
}

}  // namespace

InspectionReport run_inspection(const engine::PreparedModel& model,
                                const PointDeviations& deviations, InspectionReport report,
                                const InspectionOptions& options, const OutputFolder& folder) {
  const auto start = std::chrono::steady_clock::now();
  const ColourScale& scale = options.scale;
  report.scale = scale;
  report.min_inside = options.min_inside;
  report.picture_view = isometric_view().description;
  report.stats = compute_statistics(deviations, model.model(), scale.band, scale.lower_limit,
                                    scale.upper_limit, options.histogram_bins);
  ViewerSubset subset;
  DisplayMesh mesh;
  tbb::parallel_invoke([&] { subset = viewer_subset(deviations.points, options.viewer_points); },
                       [&] {
                         if (options.model_mesh) mesh = tessellate(model, options.mesh_vertices);
                       });
  report.viewer_points = subset.indices.size();
  report.viewer_subset =
      subset.cell == 0.0 ? "every point"
                         : fmt::format("one point per {:.4g} {} grid cell, the first in scan order",
                                       subset.cell, report.units);
  spdlog::debug("inspect: statistics, subset ({} points) and mesh ({} triangles) in {:.3f} s",
                subset.indices.size(), mesh.triangle_count(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  // inspection_seconds: statistics, subset, mesh, PLY and picture; the page and the JSON that
  // state it are written after (both show the same number).
  tbb::parallel_invoke(
      [&] { write_deviation_ply(folder.path("deviations.ply"), deviations, scale); },
      [&] {
        write_deviation_picture(folder.path("deviations.png"), deviations, mesh, report,
                                options.picture);
      });
  report.inspection_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  write_html_report(folder.path("report.html"), report, deviations, subset, mesh);
  write_text(folder.path("inspect.json"), inspection_json(report));
  write_text(folder.path("inspect_faces.csv"), faces_csv(report));
  return report;
}

}  // namespace nurbsreg::inspect
