// `nurbsreg project`: exact closest point on the model for every input point (CONTRACT.md §1).

#include <spdlog/spdlog.h>

#include "commands.hpp"
#include "common.hpp"
#include "frame_jobs.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/projection_results.hpp"

namespace nurbsreg::cli {
namespace {

struct ProjectArgs {
  std::string model;
  std::string points;
  std::string out;
  int threads = 0;
  std::string target = "surfaces";
};

void run_project(const ProjectArgs& args) {
  const auto threads = limit_threads(args.threads);
  if (!io::table_format_for(args.out)) {
    throw UsageError("--out: " + args.out + ": expected a .csv or .pcd file name");
  }
  const Stopwatch total;
  engine::Model model = load_model_file(args.model);
  const engine::ProjectionTarget target = parse_projection_target(args.target);
  check_projection_target(model, target, args.model);
  const io::PointCloud cloud = io::read_scan(args.points);
  spdlog::info("{}: {} points read, {} skipped (NaN or infinite)", args.points, cloud.size(),
               cloud.skipped_nonfinite);

  const Stopwatch prepare;
  const engine::PreparedModel prepared(std::move(model));
  spdlog::info("{}: {} Bézier patches, {} curve pieces prepared in {:.3f} s", args.model,
               prepared.patch_count(), prepared.piece_count(), prepare.seconds());

  if (const auto note = scan_size(cloud, prepared).warning()) {
    spdlog::warn("{}: {}", args.points, *note);
  }

  engine::Projector projector(prepared);
  const ProjectFrameResult r = project_frame(projector, cloud, target, args.out, true);
  spdlog::info(
      "{} points projected, {} skipped; distance min {:.6g} mean {:.6g} max {:.6g}; {:.0f} "
      "points/s; wrote {} ({:.2f} s total)",
      r.points, r.skipped, r.min_distance, r.mean_distance, r.max_distance,
      r.compute_seconds > 0 ? static_cast<double>(r.points) / r.compute_seconds : 0.0, args.out,
      total.seconds());
  // After the summary, so that it is the last line a user reads.
  if (r.far_note) spdlog::warn("{}: {}", args.points, *r.far_note);
}

}  // namespace

void add_project_command(CLI::App& app) {
  auto* cmd =
      app.add_subcommand("project", "Exact closest point on the model for every input point");
  auto args = std::make_shared<ProjectArgs>();
  cmd->add_option("--model", args->model, "Model file (.json, .step/.stp, .iges/.igs)")->required();
  cmd->add_option("--points", args->points, "Points: .pcd, .ply, .xyz/.txt/.csv")->required();
  cmd->add_option("--out", args->out, "Results: .csv or .pcd (written atomically)")->required();
  cmd->add_option("--threads", args->threads, "Worker threads (0 = all hardware threads)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--target", args->target, "Project onto the model's surfaces or its curves")
      ->check(CLI::IsMember({"surfaces", "curves"}));
  cmd->callback([args] { run_project(*args); });
}

}  // namespace nurbsreg::cli
