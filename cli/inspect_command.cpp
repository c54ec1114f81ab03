// `nurbsreg inspect`: align (unless --pose gives the final pose), then the deviation report
// (CONTRACT.md §1, §2 "Inspection"): D/inspect.json, D/inspect_faces.csv, D/deviations.ply,
// D/report.html, D/deviations.png. Thin: the alignment is registration::Aligner's, the
// inspection inspect::run_inspection's.

#include <spdlog/spdlog.h>

#include <cmath>
#include <iostream>
#include <optional>
#include <stdexcept>

#include "commands.hpp"
#include "common.hpp"
#include "frame_jobs.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/inspect/clutter.hpp"
#include "nurbsreg/inspect/inspection.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/pose.hpp"
#include "nurbsreg/registration/alignment.hpp"

namespace nurbsreg::cli {
namespace {

struct InspectArgs {
  std::string model;
  std::string scan;
  std::string init;
  std::string pose;
  std::string out_dir;
  std::optional<double> tolerance;
  std::optional<double> tolerance_upper;
  std::optional<double> tolerance_lower;
  std::string colour_scale = "metrology";
  std::optional<double> colour_min;
  std::optional<double> colour_max;
  double min_inside = 0.99;
  std::size_t viewer_points = 300'000;
  bool no_model_mesh = false;
  std::optional<double> exclude_beyond;
  IcpArgs icp;
  GlobalArgs global;
  int threads = 0;
};

// The band and the colour scale from the options, validated before any work.
inspect::ColourScale colour_scale(const InspectArgs& args) {
  if (!args.tolerance && !(args.tolerance_upper && args.tolerance_lower)) {
    throw UsageError("--tolerance is required (or both --tolerance-upper and --tolerance-lower)");
  }
  if (args.tolerance && !(*args.tolerance > 0.0 && std::isfinite(*args.tolerance))) {
    throw UsageError(
        fmt::format("--tolerance: must be a positive number (got {})", *args.tolerance));
  }
  inspect::Tolerance band;
  band.upper = args.tolerance_upper.value_or(args.tolerance.value_or(0.0));
  band.lower = args.tolerance_lower.value_or(-args.tolerance.value_or(0.0));
  if (const auto error = band.validate()) throw UsageError(*error);
  const auto scheme = inspect::parse_colour_scheme(args.colour_scale);
  if (!scheme) {
    throw UsageError("--colour-scale: expected metrology or blue-red, got \"" + args.colour_scale +
                     "\"");
  }
  inspect::ColourScale scale = inspect::ColourScale::around(band, *scheme);
  if (args.colour_min) scale.lower_limit = *args.colour_min;
  if (args.colour_max) scale.upper_limit = *args.colour_max;
  if (const auto error = scale.validate()) throw UsageError(*error);
  return scale;
}

void run_inspect(const InspectArgs& args) {
  const auto threads = limit_threads(args.threads);
  const Stopwatch total;
  if (!args.init.empty() && !args.pose.empty()) {
    throw UsageError(
        "--init and --pose exclude each other (--pose is the final pose: no alignment)");
  }
  inspect::InspectionOptions options;
  options.scale = colour_scale(args);
  options.min_inside = args.min_inside;
  options.viewer_points = args.viewer_points;
  options.model_mesh = !args.no_model_mesh;
  if (args.exclude_beyond) {
    if (const auto error = inspect::validate_exclusion(*args.exclude_beyond, options.scale.band,
                                                       "--exclude-beyond"))
      throw UsageError(*error);
  }
  const icp::IcpOptions icp = icp_options(args.icp);
  // Before the work: an output folder that cannot be written would waste it.
  std::optional<inspect::OutputFolder> folder;
  try {
    folder.emplace(args.out_dir);
  } catch (const std::runtime_error& e) {
    throw UsageError(std::string("--out-dir: ") + e.what());
  }

  engine::Model model = load_model_file(args.model);
  if (model.surfaces.empty())
    throw UsageError(args.model + ": inspect needs a model with surfaces");
  const io::PointCloud cloud = io::read_point_cloud(args.scan);
  if (cloud.size() == 0) throw io::InputError(args.scan, "no finite points to inspect");
  Eigen::Isometry3d init = Eigen::Isometry3d::Identity();
  if (!args.init.empty()) init.matrix() = io::read_pose(args.init);
  if (!args.pose.empty()) init.matrix() = io::read_pose(args.pose);
  spdlog::info("{}: {} points ({} skipped: NaN or infinite)", args.scan, cloud.size(),
               cloud.skipped_nonfinite);
  const engine::PreparedModel prepared(std::move(model));

  inspect::InspectionReport report;
  report.model_file = args.model;
  report.scan_file = args.scan;
  report.units = prepared.model().units;
  report.scan_points = cloud.size();
  inspect::PointDeviations deviations;
  const Stopwatch alignment;
  if (!args.pose.empty()) {
    // The final pose is given: the exact projection of every transformed point.
    std::vector<engine::Vec3> aligned(cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i)
      aligned[i] = init * cloud.points[i];
    engine::Projector projector(prepared);
    engine::ProjectionResults projections;
    projector.project(engine::PointView::of(aligned), engine::ProjectionOptions{}, projections);
    deviations = inspect::collect_deviations(aligned, projections, cloud.source_index,
                                             cloud.skipped_nonfinite);
    report.pose_given = true;
    report.alignment = inspect::given_pose_alignment(init.matrix(), deviations, cloud.size());
  } else {
    // As `align` does: from any pose without --init (the global stage, with the model's
    // features from the features cache), from --init as given; progress while it runs.
    const registration::RegistrationOptions registration = registration_options(args.global);
    registration::AlignRequest request = align_request(args.init, args.global);
    request.progress = log_progress;
    registration::Aligner aligner(prepared, icp, registration,
                                  features_for(prepared, request, registration, "inspect"));
    const registration::AlignmentResult frame = align_frame(aligner, cloud, request);
    // A failure's one line is its error (the brief report would say it first).
    if (frame.failure) throw std::runtime_error(args.scan + ": " + *frame.failure);
    spdlog::info("{}", frame.icp.brief_report());
    warn_if_unconverged(args.scan, frame.icp, args.icp);
    warn_about_fit(args.scan, frame);
    if (const auto note = frame.sizes.warning()) spdlog::warn("{}: {}", args.scan, *note);
    if (frame.icp.degeneracy.degenerate()) {
      report.degeneracy = frame.icp.degeneracy.describe();
      spdlog::warn("the scan does not constrain the pose fully; free directions: {}",
                   report.degeneracy);
    }
    deviations = inspect::collect_deviations(frame.aligned, aligner.last_projections(),
                                             cloud.source_index, cloud.skipped_nonfinite);
    report.alignment = alignment_report(frame, cloud, args.icp, total);
  }
  report.alignment_seconds = alignment.seconds();
  report.alignment.seconds = total.seconds();
  if (deviations.unprojected > 0) {
    spdlog::warn("{}: {} points have no closest point on the model and are not inspected",
                 args.scan, deviations.unprojected);
  }
  if (args.exclude_beyond) {
    inspect::exclude_beyond(deviations, *args.exclude_beyond);
    spdlog::warn("{}: {} points farther than {:g} from the model are excluded (--exclude-beyond)",
                 args.scan, deviations.excluded, *args.exclude_beyond);
  } else if (const auto hint = inspect::clutter_hint(deviations, options.scale.band,
                                                     options.min_inside, "--exclude-beyond")) {
    spdlog::warn("{}: {}", args.scan, *hint);
  }

  const Stopwatch inspection;
  const inspect::InspectionReport done =
      inspect::run_inspection(prepared, deviations, std::move(report), options, *folder);
  folder->commit();
  const double inspection_seconds = inspection.seconds();
  const inspect::DeviationStats& s = done.stats.overall;
  std::cout << fmt::format(
      "{}: {:.2f} % of {} points inside [{:+g}, {:+g}] {} ({} above, {} below{}): {}\n", args.scan,
      100.0 * s.inside_fraction(), s.points, done.stats.tolerance.lower, done.stats.tolerance.upper,
      done.units, s.above, s.below,
      args.exclude_beyond ? fmt::format("; {} farther than {:g} excluded", done.stats.excluded,
                                        *args.exclude_beyond)
                          : std::string(),
      done.passed() ? "PASS" : "FAIL");
  std::cout << fmt::format(
      "signed deviation: mean {:+.4g}  std {:.4g}  min {:+.4g}  max {:+.4g}  p5 {:+.4g}  p95 "
      "{:+.4g}\n",
      s.mean, s.std, s.min, s.max, s.p5, s.p95);
  std::cout << "wrote " << args.out_dir
            << "/{inspect.json, inspect_faces.csv, deviations.ply, report.html, deviations.png}\n";
  spdlog::info("alignment {:.2f} s, inspection (every output) {:.2f} s, total {:.2f} s",
               done.alignment_seconds, inspection_seconds, total.seconds());
}

}  // namespace

void add_inspect_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "inspect",
      "Align, then the deviation report: colour map (PLY, PNG), statistics per face "
      "(JSON, CSV) and a self-contained HTML page");
  auto args = std::make_shared<InspectArgs>();
  cmd->add_option("--model", args->model, "Model file (.json, .step/.stp, .iges/.igs)")->required();
  cmd->add_option("--scan", args->scan, "Scan: .pcd, .ply, .xyz/.txt/.csv")->required();
  cmd->add_option("--init", args->init,
                  "Initial pose T0 for the alignment (4 lines of 4 numbers); none: global "
                  "alignment from any pose first");
  cmd->add_option("--pose", args->pose,
                  "The final pose T: no alignment (model_point = T * scan_point)");
  cmd->add_option("--out-dir", args->out_dir, "Output folder (created; its parent must exist)")
      ->required();
  cmd->add_option("--tolerance", args->tolerance,
                  "Tolerance t > 0: the band [-t, +t] (model units)");
  cmd->add_option("--tolerance-upper", args->tolerance_upper,
                  "Upper limit of the band (default +t)");
  cmd->add_option("--tolerance-lower", args->tolerance_lower,
                  "Lower limit of the band, a signed value (default -t)");
  cmd->add_option("--colour-scale", args->colour_scale,
                  "metrology (blue-green-red, default) or blue-red");
  cmd->add_option("--colour-min", args->colour_min,
                  "Deviation where the colours saturate below the band (default 3 x lower)");
  cmd->add_option("--colour-max", args->colour_max,
                  "Deviation where the colours saturate above the band (default 3 x upper)");
  cmd->add_option(
         "--min-inside", args->min_inside,
         "Verdict: pass when at least this fraction of the points is inside (default 0.99)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--viewer-points", args->viewer_points,
                  "At most this many points in the report's 3-D view (default 300000)")
      ->check(CLI::Range(std::size_t{1}, std::size_t{5'000'000}));
  cmd->add_flag("--no-model-mesh", args->no_model_mesh, "Leave the model's grey faces out");
  cmd->add_option("--exclude-beyond", args->exclude_beyond,
                  "Leave out (and count) the points farther than this from the model: clutter "
                  "such as a fixture (model units, beyond the tolerance band)");
  add_icp_options(*cmd, args->icp);
  add_global_options(*cmd, args->global);
  cmd->add_option("--threads", args->threads, "Worker threads (0 = all hardware threads)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([args] { run_inspect(*args); });
}

}  // namespace nurbsreg::cli
