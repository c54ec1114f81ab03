// `nurbsreg project`: exact closest point on the model for every input point (CONTRACT.md §1).

#include <spdlog/spdlog.h>

#include <algorithm>
#include <limits>

#include "commands.hpp"
#include "common.hpp"
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

// Frames are projected in blocks so long runs show progress; the block size keeps logging to a
// few lines a second without costing parallelism.
constexpr std::size_t kProgressBlock = 1 << 18;

void run_project(const ProjectArgs& args) {
  const auto threads = limit_threads(args.threads);
  const Stopwatch total;
  engine::Model model = load_model_file(args.model);
  const engine::ProjectionTarget target = args.target == "curves"
                                              ? engine::ProjectionTarget::curves
                                              : engine::ProjectionTarget::surfaces;
  if (target == engine::ProjectionTarget::surfaces && model.surfaces.empty()) {
    throw UsageError(args.model + ": the model has no surfaces; use --target curves");
  }
  if (target == engine::ProjectionTarget::curves && model.curves.empty()) {
    throw UsageError(args.model + ": the model has no curves; use --target surfaces");
  }
  const io::PointCloud cloud = io::read_point_cloud(args.points);
  spdlog::info("{}: {} points read, {} skipped (NaN or infinite)", args.points, cloud.size(),
               cloud.skipped_nonfinite);

  const Stopwatch prepare;
  const engine::PreparedModel prepared(std::move(model));
  spdlog::info("{}: {} Bézier patches, {} curve pieces prepared in {:.3f} s", args.model,
               prepared.patch_count(), prepared.piece_count(), prepare.seconds());

  engine::Projector projector(prepared);
  engine::ProjectionOptions options;
  options.target = target;
  engine::ProjectionResults results;
  results.resize(cloud.size());
  engine::ProjectionResults block;
  const Stopwatch compute;
  for (std::size_t begin = 0; begin < cloud.size(); begin += kProgressBlock) {
    const std::size_t end = std::min(cloud.size(), begin + kProgressBlock);
    const std::span<const engine::Vec3> part(cloud.points.data() + begin, end - begin);
    projector.project(engine::PointView::of(part), options, block);
    results.copy_from(block, begin);
    if (cloud.size() > kProgressBlock) {
      spdlog::info("projected {}/{} points ({:.0f} points/s)", end, cloud.size(),
                   static_cast<double>(end) / compute.seconds());
    }
  }
  const double seconds = compute.seconds();

  std::vector<double> normal_x(cloud.size());
  std::vector<double> normal_y(cloud.size());
  std::vector<double> normal_z(cloud.size());
  double min_d = std::numeric_limits<double>::infinity();
  double max_d = 0.0;
  double sum_d = 0.0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    normal_x[i] = results.normal[i].x();
    normal_y[i] = results.normal[i].y();
    normal_z[i] = results.normal[i].z();
    min_d = std::min(min_d, results.distance[i]);
    max_d = std::max(max_d, results.distance[i]);
    sum_d += results.distance[i];
  }
  io::ProjectionColumns columns;
  columns.index = cloud.source_index;
  columns.point = cloud.points;
  columns.foot = results.foot;
  columns.distance = results.distance;
  columns.entity = results.entity;
  columns.u = results.u;
  columns.v = results.v;
  if (target == engine::ProjectionTarget::surfaces) {
    columns.extra = {{"signed_distance", results.signed_distance},
                     {"normal_x", normal_x},
                     {"normal_y", normal_y},
                     {"normal_z", normal_z}};
  }
  io::write_projection_results(args.out, columns);
  const double mean = cloud.size() ? sum_d / static_cast<double>(cloud.size()) : 0.0;
  spdlog::info(
      "{} points projected, {} skipped; distance min {:.6g} mean {:.6g} max {:.6g}; {:.0f} "
      "points/s; wrote {} ({:.2f} s total)",
      cloud.size(), cloud.skipped_nonfinite, cloud.size() ? min_d : 0.0, mean, max_d,
      seconds > 0 ? static_cast<double>(cloud.size()) / seconds : 0.0, args.out, total.seconds());
}

}  // namespace

void add_project_command(CLI::App& app) {
  auto* cmd =
      app.add_subcommand("project", "Exact closest point on the model for every input point");
  auto args = std::make_shared<ProjectArgs>();
  cmd->add_option("--model", args->model, "Model file (.json)")->required();
  cmd->add_option("--points", args->points, "Points: .pcd, .ply, .xyz/.txt/.csv")->required();
  cmd->add_option("--out", args->out, "Results: .csv or .pcd (written atomically)")->required();
  cmd->add_option("--threads", args->threads, "Worker threads (0 = all hardware threads)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--target", args->target, "Project onto the model's surfaces or its curves")
      ->check(CLI::IsMember({"surfaces", "curves"}));
  cmd->callback([args] { run_project(*args); });
}

}  // namespace nurbsreg::cli
