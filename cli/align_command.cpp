// `nurbsreg align`: the rigid pose that maps a scan onto the model (ICP on exact projections),
// and how well it fits (CONTRACT.md §1).

#include <spdlog/spdlog.h>

#include <iostream>
#include <sstream>
#include <stdexcept>

#include "commands.hpp"
#include "common.hpp"
#include "frame_jobs.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/pose.hpp"
#include "nurbsreg/io/projection_results.hpp"
#include "nurbsreg/registration/alignment.hpp"

namespace nurbsreg::cli {
namespace {

struct AlignArgs {
  std::string model;
  std::string scan;
  std::string init;
  std::string out_pose;
  std::string aligned;
  std::string report;
  IcpArgs icp;
  GlobalArgs global;
  int threads = 0;
};

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
  // Before any work: a wrong name found after the alignment would waste it.
  if (!args.aligned.empty() && !io::table_format_for(args.aligned)) {
    throw UsageError("--aligned: " + args.aligned + ": expected a .pcd or .csv file name");
  }
  const Stopwatch total;
  const icp::IcpOptions options = icp_options(args.icp);
  engine::Model model = load_model_file(args.model);
  if (model.surfaces.empty()) throw UsageError(args.model + ": align needs a model with surfaces");
  const io::PointCloud cloud = io::read_scan(args.scan);
  registration::AlignRequest request = align_request(args.init, args.global);
  // Only --aligned writes per-point distances; the rest reads the summary and the verdict.
  request.all_projections = !args.aligned.empty();
  // A long alignment says where it is (a 1 M-point scan takes seconds).
  request.progress = log_progress;
  spdlog::info("{}: {} points ({} skipped: NaN or infinite)", args.scan, cloud.size(),
               cloud.skipped_nonfinite);

  const engine::PreparedModel prepared(std::move(model));
  const registration::RegistrationOptions registration = registration_options(args.global);
  // From any pose the alignment needs every part of the model's features: from the cache.
  const Stopwatch features_wall;
  const double features_cpu0 = process_cpu_seconds();
  const std::shared_ptr<const registration::ModelFeatures> features =
      features_for(prepared, request, registration, "align");
  const double features_seconds = features_wall.seconds();
  const double features_cpu_seconds = process_cpu_seconds() - features_cpu0;
  registration::Aligner aligner(prepared, options, registration, features);
  registration::AlignmentResult frame = align_frame(aligner, cloud, request);
  // The report's model-features time is this run's: the load (a cache hit, or the build) too.
  if (auto& c = frame.coarse; c && features) {
    c->model_features_seconds += features_seconds;
    c->model_features_cpu_seconds += features_cpu_seconds;
  }
  const icp::IcpResult& result = frame.icp;
  const registration::DeviationSummary& dev = frame.deviation;
  if (const auto& failure = frame.failure) {
    // No pose and no aligned scan: they would align nothing. The report says what happened
    // (converged: false, the termination and every iteration).
    write_align_outputs(frame, aligner, cloud, args.icp, AlignOutputs{"", "", args.report}, total);
    throw std::runtime_error(args.scan + ": " + *failure);
  }
  // After the failure check: a failed alignment's one line is its error (the brief report would
  // say the same thing first).
  spdlog::info("{}", result.brief_report());
  warn_if_unconverged(args.scan, result, args.icp);
  warn_about_fit(args.scan, frame);
  if (const auto note = frame.sizes.warning()) spdlog::warn("{}: {}", args.scan, *note);
  if (result.degeneracy.degenerate()) {
    spdlog::warn("the scan does not constrain the pose fully; free directions: {}",
                 result.degeneracy.describe());
  }

  std::cout << "pose (model_point = T * scan_point):\n" << pose_lines(result.T_model_scan.matrix());
  std::cout << fmt::format("rms {:.6g} over {}/{} inliers, {} iterations, {} ({})\n", result.rms,
                           result.inliers, result.points, result.iterations,
                           icp::to_string(result.termination), result.message);
  // The bound and what it left out: with clutter in the scan, "of N points" alone reads as the
  // whole scan.
  std::cout << fmt::format(
      "deviation |d| of {} points within {:.4g} (the max distance; {} beyond): mean {:.4g}  rms "
      "{:.4g}  median {:.4g}  p95 {:.4g}  p99 {:.4g}  max {:.4g}\n",
      dev.count, dev.within, result.points - std::min(result.points, dev.count), dev.mean, dev.rms,
      dev.p50, dev.p95, dev.p99, dev.max);
  if (result.degeneracy.degenerate()) {
    std::cout << "degenerate: unconstrained " << result.degeneracy.describe() << "\n";
  }
  if (const auto& c = frame.coarse) {
    std::cout << fmt::format(
        "coarse: {} ({} scan / {} model keypoints, {} matches, {} hypotheses verified) in {:.2f} "
        "s; winner {:.1f}% inliers{}\n",
        c->method, c->scan_keypoints, c->model_keypoints, c->matches, c->verified, c->seconds,
        100.0 * c->winner.inlier_fraction,
        c->runner_up ? fmt::format(", runner-up {:.1f}%", 100.0 * c->runner_up->inlier_fraction)
                     : std::string());
  }
  const registration::FitVerdict& fit = frame.fit;
  // Where the tolerance came from: a scan whose noise could not be estimated gets the model's
  // floor, and "3 x noise 0" would read as a bug.
  // When the distances at the pose tightened the scan's own estimate, both are shown.
  const std::string tightened =
      fit.noise < fit.scan_noise
          ? fmt::format(" of the distances; the scan's own estimate {:.3g}", fit.scan_noise)
          : std::string();
  const std::string basis =
      fit.noise > 0.0
          ? fmt::format("{:.3g} x noise {:.3g}{}", fit.tolerance / fit.noise, fit.noise, tightened)
          : std::string("noise not estimated: the model's floor");
  std::cout << fmt::format(
      "fit {}: {:.1f}% of the points within {:.3g} ({}), rms {:.3g}, model coverage {:.1f}%\n",
      fit.word(), 100.0 * fit.inlier_fraction, fit.tolerance, basis, fit.rms, 100.0 * fit.coverage);
  write_align_outputs(frame, aligner, cloud, args.icp,
                      AlignOutputs{args.out_pose, args.aligned, args.report}, total);
  spdlog::info("aligned {} points in {:.2f} s", cloud.size(), total.seconds());
}

}  // namespace

void add_align_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("align", "ICP: the rigid pose that maps the scan onto the model");
  auto args = std::make_shared<AlignArgs>();
  cmd->add_option("--model", args->model, "Model file (.json, .step/.stp, .iges/.igs)")->required();
  cmd->add_option("--scan", args->scan, "Scan: .pcd, .ply, .xyz/.txt/.csv")->required();
  cmd->add_option("--init", args->init,
                  "Initial pose T0 (4 lines of 4 numbers): ICP from it as given; \"auto\" or "
                  "none: global alignment from any pose first");
  cmd->add_option("--out-pose", args->out_pose, "Write the pose T (model_point = T * scan_point)");
  cmd->add_option("--aligned", args->aligned,
                  "Write the aligned scan (.pcd or .csv) with signed_distance, entity, u, v per "
                  "point");
  cmd->add_option("--report", args->report, "Write a JSON report");
  add_icp_options(*cmd, args->icp);
  add_global_options(*cmd, args->global);
  cmd->add_option("--threads", args->threads, "Worker threads (0 = all hardware threads)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([args] { run_align(*args); });
}

}  // namespace nurbsreg::cli
