// `nurbsreg align`: the rigid pose that maps a scan onto the model (ICP on exact projections),
// and how well it fits (CONTRACT.md §1).

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "commands.hpp"
#include "common.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/io/alignment_report.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/point_table.hpp"
#include "nurbsreg/io/pose.hpp"

namespace nurbsreg::cli {
namespace {

struct AlignArgs {
  std::string model;
  std::string scan;
  std::string init;
  std::string out_pose;
  std::string aligned;
  std::string report;
  std::string method = "point-to-plane";
  int max_iterations = 50;
  double max_distance = std::numeric_limits<double>::infinity();
  double keep_fraction = 1.0;
  std::string kernel = "none";
  double kernel_scale = 0.0;
  std::vector<std::size_t> coarse;
  int threads = 0;
};

icp::IcpOptions icp_options(const AlignArgs& args) {
  icp::IcpOptions options;
  const auto method = icp::parse_icp_method(args.method);
  if (!method) throw UsageError("--method: expected point-to-plane or point-to-point");
  options.method = *method;
  const auto kernel = icp::parse_robust_kernel(args.kernel);
  if (!kernel) throw UsageError("--kernel: expected none, huber, tukey or geman-mcclure");
  options.kernel = *kernel;
  options.kernel_scale = args.kernel_scale;
  options.max_iterations = args.max_iterations;
  options.max_correspondence_distance = args.max_distance;
  options.keep_fraction = args.keep_fraction;
  options.coarse_sizes = args.coarse;
  if (auto error = options.validate()) throw UsageError(*error);
  return options;
}

// Deviation of the aligned scan from the model: order statistics of |d| over the inliers.
struct Deviation {
  double mean = 0, rms = 0, p50 = 0, p95 = 0, p99 = 0, max = 0;
};

Deviation summarise(std::vector<double> distances) {
  Deviation d;
  if (distances.empty()) return d;
  double sum = 0.0;
  double sum_sq = 0.0;
  for (double x : distances) {
    sum += x;
    sum_sq += x * x;
  }
  std::sort(distances.begin(), distances.end());
  auto quantile = [&](double q) {
    return distances[static_cast<std::size_t>(q * static_cast<double>(distances.size() - 1))];
  };
  d.mean = sum / static_cast<double>(distances.size());
  d.rms = std::sqrt(sum_sq / static_cast<double>(distances.size()));
  d.p50 = quantile(0.5);
  d.p95 = quantile(0.95);
  d.p99 = quantile(0.99);
  d.max = distances.back();
  return d;
}

std::string pose_lines(const Eigen::Matrix4d& T) {
  std::ostringstream out;
  out.precision(9);
  for (int r = 0; r < 4; ++r) {
    out << "  ";
    for (int c = 0; c < 4; ++c)
      out << (c ? " " : "") << T(r, c);
    out << "\n";
  }
  return out.str();
}

void run_align(const AlignArgs& args) {
  const auto threads = limit_threads(args.threads);
  const Stopwatch total;
  const icp::IcpOptions options = icp_options(args);
  engine::Model model = load_model_file(args.model);
  if (model.surfaces.empty()) throw UsageError(args.model + ": align needs a model with surfaces");
  const io::PointCloud cloud = io::read_point_cloud(args.scan);
  if (cloud.size() == 0) throw io::InputError(args.scan, "no finite points to align");
  Eigen::Isometry3d init = Eigen::Isometry3d::Identity();
  if (!args.init.empty()) init.matrix() = io::read_pose(args.init);
  spdlog::info("{}: {} points ({} skipped: NaN or infinite)", args.scan, cloud.size(),
               cloud.skipped_nonfinite);

  const engine::PreparedModel prepared(std::move(model));
  icp::ModelCorrespondenceFinder finder(prepared);
  icp::IcpSolver solver(options);
  const icp::IcpResult result = solver.align(finder, cloud.points, init);
  for (const icp::IcpIteration& it : result.log) {
    spdlog::debug("stage {} rms {:.6g} inliers {}/{} step {:.3g} rad {:.3g}", it.stage, it.rms,
                  it.inliers, it.points, it.rotation_step, it.translation_step);
  }
  if (result.termination == icp::IcpTermination::invalid_input) {
    throw UsageError("align: " + result.message);
  }
  spdlog::info("{}", result.brief_report());
  if (result.degeneracy.degenerate()) {
    spdlog::warn("the scan does not constrain the pose fully; free directions: {}",
                 result.degeneracy.describe());
  }

  // Final per-point deviations at the solved pose (exact projections, warm-started).
  std::vector<engine::Vec3> aligned(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i)
    aligned[i] = result.T_model_scan * cloud.points[i];
  std::vector<icp::Correspondence> correspondences(cloud.size());
  icp::CorrespondenceQuery query;
  query.points = aligned;
  finder.find(query, correspondences);
  const engine::ProjectionResults& proj = finder.last_results();
  std::vector<double> inlier_distances;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (proj.distance[i] <= args.max_distance) inlier_distances.push_back(proj.distance[i]);
  }
  const Deviation dev = summarise(inlier_distances);

  std::cout << "pose (model_point = T * scan_point):\n" << pose_lines(result.T_model_scan.matrix());
  std::cout << fmt::format("rms {:.6g} over {}/{} inliers, {} iterations, {} ({})\n", result.rms,
                           result.inliers, result.points, result.iterations,
                           icp::to_string(result.termination), result.message);
  std::cout << fmt::format(
      "deviation |d| of {} points within max distance: mean {:.4g}  rms {:.4g}  median {:.4g}  "
      "p95 {:.4g}  p99 {:.4g}  max {:.4g}\n",
      inlier_distances.size(), dev.mean, dev.rms, dev.p50, dev.p95, dev.p99, dev.max);
  if (result.degeneracy.degenerate()) {
    std::cout << "degenerate: unconstrained " << result.degeneracy.describe() << "\n";
  }

  if (!args.out_pose.empty()) io::write_pose(args.out_pose, result.T_model_scan.matrix());
  if (!args.aligned.empty()) {
    io::PointTable table;
    auto& x = table.add_column<float>("x");
    auto& y = table.add_column<float>("y");
    auto& z = table.add_column<float>("z");
    auto& signed_distance = table.add_column<float>("signed_distance");
    auto& entity = table.add_column<std::int32_t>("entity");
    auto& u = table.add_column<double>("u");
    auto& v = table.add_column<double>("v");
    auto& index = table.add_column<std::uint64_t>("index");
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      x.push_back(static_cast<float>(aligned[i].x()));
      y.push_back(static_cast<float>(aligned[i].y()));
      z.push_back(static_cast<float>(aligned[i].z()));
      signed_distance.push_back(static_cast<float>(proj.signed_distance[i]));
      entity.push_back(proj.entity[i]);
      u.push_back(proj.u[i]);
      v.push_back(proj.v[i]);
      index.push_back(cloud.source_index[i]);
    }
    io::write_point_table(args.aligned, table);
  }
  if (!args.report.empty()) {
    io::AlignmentReport report;
    report.pose = result.T_model_scan.matrix();
    report.rms = result.rms;
    report.iterations = result.iterations;
    report.converged = result.converged();
    report.inliers = result.inliers;
    report.points = result.points;
    report.skipped_points = cloud.skipped_nonfinite;
    report.seconds = total.seconds();
    report.method = args.method;
    report.termination = std::string(icp::to_string(result.termination)) + ": " + result.message;
    int k = 0;
    for (const icp::IcpIteration& it : result.log) {
      report.history.push_back(
          {++k, it.rms, it.inliers, it.rotation_step, it.translation_step, it.seconds});
    }
    io::write_alignment_report(args.report, report);
  }
  spdlog::info("aligned {} points in {:.2f} s", cloud.size(), total.seconds());
}

}  // namespace

void add_align_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("align", "ICP: the rigid pose that maps the scan onto the model");
  auto args = std::make_shared<AlignArgs>();
  cmd->add_option("--model", args->model, "Model file (.json)")->required();
  cmd->add_option("--scan", args->scan, "Scan: .pcd, .ply, .xyz/.txt/.csv")->required();
  cmd->add_option("--init", args->init, "Initial pose T0 (4 lines of 4 numbers)");
  cmd->add_option("--out-pose", args->out_pose, "Write the pose T (model_point = T * scan_point)");
  cmd->add_option("--aligned", args->aligned,
                  "Write the aligned scan (.pcd) with signed_distance, entity, u, v per point");
  cmd->add_option("--report", args->report, "Write a JSON report");
  cmd->add_option("--method", args->method, "point-to-plane (default) or point-to-point")
      ->check(CLI::IsMember({"point-to-plane", "point-to-point"}));
  cmd->add_option("--max-iterations", args->max_iterations, "Per stage")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--max-distance", args->max_distance,
                  "Reject correspondences farther apart (model units)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--keep-fraction", args->keep_fraction,
                  "Trimmed ICP: keep this fraction of the closest correspondences")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--kernel", args->kernel, "Robust kernel: none, huber, tukey, geman-mcclure");
  cmd->add_option("--kernel-scale", args->kernel_scale, "Kernel scale (0: from the MAD)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--coarse", args->coarse,
                  "Coarse-to-fine subsample sizes, increasing (e.g. --coarse 2000 20000)");
  cmd->add_option("--threads", args->threads, "Worker threads (0 = all hardware threads)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([args] { run_align(*args); });
}

}  // namespace nurbsreg::cli
