#include "nurbsreg/inspect/inspection.hpp"
#include "nurbsreg/engine/cancellation.hpp"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>
#include <tbb/parallel_invoke.h>

#include <chrono>
#include <cmath>
#include <ctime>

#include "nurbsreg/inspect/deviation_ply.hpp"
#include "nurbsreg/inspect/html_report.hpp"
#include "nurbsreg/inspect/tessellation.hpp"
#include "nurbsreg/inspect/viewer_subset.hpp"
#include "nurbsreg/io/atomic_file.hpp"

namespace nurbsreg::inspect {
namespace {

// Wall and process CPU seconds since construction, for the stage log (-v): the CPU time says
// what a stage costs on a machine shared with other work.
class StageClock {
 public:
  void log(const char* stage) {
    const auto now = std::chrono::steady_clock::now();
    const std::clock_t cpu = std::clock();
    spdlog::debug("inspect: {} {:.3f} s (cpu {:.3f} s)", stage,
                  std::chrono::duration<double>(now - wall_).count(),
                  double(cpu - cpu_) / CLOCKS_PER_SEC);
    wall_ = now;
    cpu_ = cpu;
  }

 private:
  std::chrono::steady_clock::time_point wall_ = std::chrono::steady_clock::now();
  std::clock_t cpu_ = std::clock();
};

void write_text(const std::string& path, const std::string& text) {
  io::write_atomically(path, [&](std::ostream& out) {
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
  });
}

}  // namespace

InspectionOutputs InspectionOutputs::in(const OutputFolder& folder) {
  return {folder.path("deviations.ply"), folder.path("deviations.png"), folder.path("report.html"),
          folder.path("inspect.json"), folder.path("inspect_faces.csv")};
}

InspectionReport run_inspection(const engine::PreparedModel& model,
                                const PointDeviations& deviations, InspectionReport report,
                                const InspectionOptions& options, const OutputFolder& folder) {
  return run_inspection(model, deviations, std::move(report), options,
                        InspectionOutputs::in(folder));
}

InspectionReport run_inspection(const engine::PreparedModel& model,
                                const PointDeviations& deviations, InspectionReport report,
                                const InspectionOptions& options, const InspectionOutputs& out) {
  const auto start = std::chrono::steady_clock::now();
  const std::clock_t cpu_start = std::clock();
  StageClock stage;
  const ColourScale& scale = options.scale;
  report.scale = scale;
  report.min_inside = options.min_inside;
  report.picture_view = isometric_view().description;
  report.stats = compute_statistics(deviations, model.model(), scale.band, scale.lower_limit,
                                    scale.upper_limit, options.histogram_bins);
  stage.log("statistics");
  ViewerSubset subset;
  DisplayMesh mesh;
  const bool needs_mesh = options.model_mesh && !(out.html.empty() && out.png.empty());
  tbb::parallel_invoke([&] { subset = viewer_subset(deviations.points, options.viewer_points); },
                       [&] {
                         if (needs_mesh) mesh = tessellate(model, options.mesh_vertices);
                       });
  nurbsreg::engine::stop_if_cancelled();
  report.viewer_points = subset.indices.size();
  report.viewer_subset =
      subset.cell == 0.0 ? "every point"
                         : fmt::format("one point per {:.4g} {} grid cell, the first in scan order",
                                       subset.cell, report.units);
  spdlog::debug("inspect: {} points in the view, {} triangles of the model", subset.indices.size(),
                mesh.triangle_count());
  stage.log("subset and mesh");
  // inspection_seconds: statistics, subset, mesh, PLY and picture; the page and the JSON that
  // state it are written after (both show the same number).
  tbb::parallel_invoke(
      [&] {
        if (!out.ply.empty()) write_deviation_ply(out.ply, deviations, scale);
      },
      [&] {
        if (!out.png.empty())
          write_deviation_picture(out.png, deviations, mesh, report, options.picture);
      });
  nurbsreg::engine::stop_if_cancelled();
  report.inspection_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stage.log("PLY and picture");
  if (!out.html.empty()) write_html_report(out.html, report, deviations, subset, mesh);
  stage.log("report.html");
  if (!out.json.empty()) write_text(out.json, inspection_json(report));
  if (!out.csv.empty()) write_text(out.csv, faces_csv(report));
  stage.log("JSON and CSV");
  spdlog::debug("inspect: all outputs {:.3f} s (cpu {:.3f} s)",
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                double(std::clock() - cpu_start) / CLOCKS_PER_SEC);
  return report;
}

io::AlignmentReport given_pose_alignment(const Eigen::Matrix4d& pose,
                                         const PointDeviations& deviations,
                                         std::size_t scan_points) {
  io::AlignmentReport a;
  a.pose = pose;
  a.points = scan_points;
  a.inliers = deviations.size();
  a.skipped_points = deviations.skipped_nonfinite;
  a.converged = true;
  a.method = "none";
  a.termination = "pose given (--pose): no alignment";
  double sum_sq = 0.0;
  for (const double d : deviations.signed_distance)
    sum_sq += d * d;
  a.rms = deviations.size() ? std::sqrt(sum_sq / double(deviations.size())) : NAN;
  return a;
}

}  // namespace nurbsreg::inspect
