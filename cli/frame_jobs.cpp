#include "frame_jobs.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>

#include "nurbsreg/io/alignment_report.hpp"
#include "nurbsreg/io/alignment_result_report.hpp"
#include "nurbsreg/io/point_table.hpp"
#include "nurbsreg/io/pose.hpp"
#include "nurbsreg/io/projected_cloud.hpp"
#include "nurbsreg/io/projection_results.hpp"

namespace nurbsreg::cli {

engine::ProjectionTarget parse_projection_target(const std::string& target) {
  if (target == "surfaces") return engine::ProjectionTarget::surfaces;
  if (target == "curves") return engine::ProjectionTarget::curves;
  throw UsageError("--target: expected surfaces or curves, got \"" + target + "\"");
}

void check_projection_target(const engine::Model& model, engine::ProjectionTarget target,
                             const std::string& model_path) {
  if (target == engine::ProjectionTarget::surfaces && model.surfaces.empty()) {
    throw UsageError(model_path + ": the model has no surfaces; use --target curves");
  }
  if (target == engine::ProjectionTarget::curves && model.curves.empty()) {
    throw UsageError(model_path + ": the model has no curves; use --target surfaces");
  }
}

ProjectFrameResult project_frame(engine::Projector& projector, const io::PointCloud& cloud,
                                 engine::ProjectionTarget target, const std::string& out,
                                 bool log_progress) {
  io::ProjectProgress progress;
  if (log_progress && cloud.size() > io::kProjectBlock) {
    progress = [](std::size_t done, std::size_t total, double seconds) {
      spdlog::info("projected {}/{} points ({:.0f} points/s)", done, total,
                   static_cast<double>(done) / seconds);
    };
  }
  const io::ProjectedCloud projected = io::project_cloud(projector, cloud, target, progress);
  io::write_projection_results(out, projected.columns(cloud));
  ProjectFrameResult summary;
  summary.compute_seconds = projected.compute_seconds;
  summary.points = cloud.size();
  summary.skipped = cloud.skipped_nonfinite;
  summary.min_distance = projected.min_distance;
  summary.max_distance = projected.max_distance;
  summary.mean_distance = projected.mean_distance;
  summary.rms_distance = projected.rms_distance;
  const engine::PreparedModel& model = projector.model();
  summary.far_note = registration::far_from_model_note(
      projected.results.distance, registration::model_size(model), model.model().units);
  return summary;
}

void add_icp_options(CLI::App& cmd, IcpArgs& args) {
  cmd.add_option("--method", args.method, "point-to-plane (default) or point-to-point")
      ->check(CLI::IsMember({"point-to-plane", "point-to-point"}));
  cmd.add_option("--max-iterations", args.max_iterations, "Per stage")->check(CLI::PositiveNumber);
  cmd.add_option("--max-distance", args.max_distance,
                 "Reject correspondences farther apart (model units)")
      ->check(CLI::PositiveNumber);
  cmd.add_option("--keep-fraction", args.keep_fraction,
                 "Trimmed ICP: keep this fraction of the closest correspondences")
      ->check(CLI::Range(0.0, 1.0));
  cmd.add_option("--kernel", args.kernel, "Robust kernel: none, huber, tukey, geman-mcclure");
  cmd.add_option("--kernel-scale", args.kernel_scale, "Kernel scale (0: from the MAD)")
      ->check(CLI::NonNegativeNumber);
  cmd.add_option("--coarse", args.coarse,
                 "Coarse-to-fine subsample sizes, increasing (e.g. --coarse 2000 20000)");
}

icp::IcpOptions icp_options(const IcpArgs& args) {
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

void add_global_options(CLI::App& cmd, GlobalArgs& args) {
  cmd.add_flag("--no-global", args.no_global,
               "No global coarse alignment: ICP from --init, or from the identity");
  cmd.add_flag("--accept-poor", args.accept_poor,
               "Report a poor fit (\"fit\": \"poor\") instead of failing");
  cmd.add_option("--min-inlier-fraction", args.min_inlier_fraction,
                 "A fit with fewer scan points within 3 x the scan's noise of the model is poor")
      ->check(CLI::Range(0.0, 1.0));
}

registration::AlignRequest align_request(const std::string& init, const GlobalArgs& args) {
  registration::AlignRequest request;
  if (init == "auto") {
    request.global = registration::GlobalMode::on;
  } else if (!init.empty()) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.matrix() = io::read_pose(init);
    request.init = T;
  }
  if (args.no_global) {
    if (init == "auto") throw UsageError("--init auto and --no-global contradict each other");
    request.global = registration::GlobalMode::off;
  }
  return request;
}

registration::RegistrationOptions registration_options(const GlobalArgs& args) {
  registration::RegistrationOptions o;
  o.verdict.accept_poor = args.accept_poor;
  o.verdict.min_inlier_fraction = args.min_inlier_fraction;
  return o;
}

std::shared_ptr<const registration::ModelFeatures> features_for(
    const engine::PreparedModel& model, const registration::AlignRequest& request,
    const registration::RegistrationOptions& registration, const std::string& command) {
  try {
    if (!request.runs_global()) return cached_features(model, registration.global.features);
    return load_features(model, registration.global.features);
  } catch (const std::runtime_error& e) {
    throw UsageError(command + ": " + e.what());  // as the aligner reports it
  }
}

void log_progress(const std::string& line) {
  spdlog::info("{}", line);
}

registration::AlignmentResult align_frame(registration::Aligner& aligner,
                                          const io::PointCloud& cloud,
                                          const registration::AlignRequest& request) {
  try {
    return aligner.align(cloud.points, request);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

void warn_about_fit(const std::string& scan, const registration::AlignmentResult& frame) {
  if (frame.fit.evaluated && !frame.fit.good) {
    spdlog::warn("{}: accepted although {}", scan, frame.fit.reason);
  }
  if (frame.coarse && !frame.coarse->alternatives.empty()) {
    spdlog::warn(
        "{}: {} other pose(s) fit as well as this one (inliers {:.1f}% vs {:.1f}%): the part "
        "looks symmetric under {}; the report lists them",
        scan, frame.coarse->alternatives.size(),
        100.0 * frame.coarse->alternatives.front().inlier_fraction,
        100.0 * frame.coarse->winner.inlier_fraction, frame.coarse->symmetry);
  }
}

registration::ScanSize scan_size(const io::PointCloud& cloud, const engine::PreparedModel& model) {
  return registration::scan_size(cloud.points, model);
}

void warn_if_unconverged(const std::string& scan, const icp::IcpResult& result,
                         const IcpArgs& args) {
  if (result.termination != icp::IcpTermination::max_iterations) return;
  spdlog::warn("{}: no convergence within {} iterations per stage; the pose may be inaccurate",
               scan, args.max_iterations);
}

io::AlignmentReport alignment_report(const registration::AlignmentResult& frame,
                                     const io::PointCloud& cloud, const IcpArgs& args,
                                     const Stopwatch& clock) {
  return io::make_alignment_report(frame, *icp::parse_icp_method(args.method),
                                   cloud.skipped_nonfinite, clock.seconds());
}

void write_align_outputs(const registration::AlignmentResult& frame,
                         const registration::Aligner& aligner, const io::PointCloud& cloud,
                         const IcpArgs& args, const AlignOutputs& outputs, const Stopwatch& clock) {
  const icp::IcpResult& result = frame.icp;
  const std::vector<engine::Vec3>& aligned = frame.aligned;

  if (!outputs.pose.empty()) io::write_pose(outputs.pose, result.T_model_scan.matrix());
  if (!outputs.aligned.empty()) {
    const engine::ProjectionResults& proj = aligner.last_projections();
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
    io::write_point_table(outputs.aligned, table);
  }
  if (!outputs.report.empty()) {
    const io::AlignmentReport report = alignment_report(frame, cloud, args, clock);
    io::write_alignment_report(outputs.report, report);
  }
}

}  // namespace nurbsreg::cli
