// `nurbsreg modify`: moves the nose points of one curve's segments to targets (seed paper 004,
// Lu & Huang 1998), e.g. to adjust a CAD profile to what a scan shows was actually built.
//
//   nurbsreg modify --model M --curve NAME (--targets T.csv | --points S)
//                   [--method points|weights|weights-knots|combined] [--iterate]
//                   [--rho-min R] [--max-iterations N] [--nose mean|nearest]
//                   --out M2.json [--report R.json]
//
// T.csv: header `segment,x,y,z` (z optional), one row per segment to move; segment = 0-based
// index of the curve's non-empty knot span. With --points the target of every segment is the
// scanned point nearest to its nose point. Segments without a target are held in place. M2.json
// is the whole model with that curve replaced. Bad input throws io::InputError (exit 3).

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

#include "commands.hpp"
#include "common.hpp"
#include "nurbsreg/engine/curve_modification.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "nurbsreg/io/modify_io.hpp"
#include "nurbsreg/io/point_cloud.hpp"

namespace nurbsreg::cli {

namespace {

struct ModifyArgs {
  std::string model;
  std::string curve;
  std::string targets;
  std::string points;
  std::string method = "points";
  std::string nose = "mean";
  bool iterate = false;
  double rho_min = 0.25;
  int max_iterations = 10;
  std::string out;
  std::string report;
};

engine::ModifyMethod parse_method(const std::string& s) {
  if (s == "points") return engine::ModifyMethod::points;
  if (s == "weights") return engine::ModifyMethod::weights;
  if (s == "weights-knots") return engine::ModifyMethod::weights_knots;
  return engine::ModifyMethod::combined;  // CLI11 restricts the choices
}

void run_modify(const ModifyArgs& args) {
  engine::Model model = load_model_file(args.model);
  auto it = std::find_if(model.curves.begin(), model.curves.end(),
                         [&](const engine::NurbsCurve& c) { return c.name == args.curve; });
  if (it == model.curves.end()) {
    std::string names;
    for (const engine::NurbsCurve& c : model.curves)
      names += (names.empty() ? "" : ", ") + c.name;
    throw io::InputError(args.model, "no curve named \"" + args.curve +
                                         "\" (curves: " + (names.empty() ? "none" : names) + ")");
  }
  engine::NurbsCurve& curve = *it;

  engine::ModifyOptions options;
  options.method = parse_method(args.method);
  options.nose_rule = args.nose == "nearest" ? engine::NoseRule::nearest_to_control_point
                                             : engine::NoseRule::mean_parameter;
  options.iterate = args.iterate;
  options.rho_min = args.rho_min;
  options.max_iterations = args.max_iterations;

  const std::vector<engine::NosePoint> noses = engine::nose_points(curve, options.nose_rule);
  const int segments = static_cast<int>(noses.size());
  std::vector<engine::SegmentTarget> targets;
  std::string source;
  if (!args.targets.empty()) {
    targets = io::read_modify_targets(args.targets);
    for (const engine::SegmentTarget& t : targets) {
      if (t.segment >= segments) {
        throw io::InputError(args.targets, "target for segment " + std::to_string(t.segment) +
                                               ", but curve \"" + curve.name + "\" has " +
                                               std::to_string(segments) + " segments (0.." +
                                               std::to_string(segments - 1) + ")");
      }
      if (curve.dimension == 2 && t.point.z() != 0.0) {
        throw io::InputError(args.targets, "segment " + std::to_string(t.segment) +
                                               ": z must be 0 (curve \"" + curve.name +
                                               "\" is planar)");
      }
    }
    source = args.targets;
  } else {
    const io::PointCloud cloud = io::read_scan(args.points);
    targets = io::nearest_scan_targets(cloud.points, noses, args.points);
    source = args.points + " (nearest of " + std::to_string(cloud.size()) + " points)";
  }

  io::ModifyReport report;
  report.model_file = args.model;
  report.curve_name = curve.name;
  report.target_source = source;
  report.options = options;
  report.targets = targets;
  try {
    report.result = engine::modify_curve(curve, targets, options);
  } catch (const std::invalid_argument& e) {
    throw io::InputError(args.targets.empty() ? args.points : args.targets, e.what());
  }
  curve = report.result.curve;
  io::write_model(args.out, model);
  if (!args.report.empty()) io::write_modify_report(args.report, report);

  std::printf("curve \"%s\": %d segments, %zu targets, method %s%s\n", curve.name.c_str(), segments,
              targets.size(), io::to_string(options.method), options.iterate ? " (iterated)" : "");
  std::printf("%-6s %-8s %14s %9s\n", "step", "op", "total error", "rho");
  for (std::size_t k = 0; k < report.result.steps.size(); ++k) {
    const engine::ModifyStep& s = report.result.steps[k];
    std::printf("%-6zu %-8s %14.6g %9.4f%s\n", k, s.operation.c_str(), s.total, s.rho,
                s.reverted ? "  (reverted)" : "");
  }
  std::printf("termination: %s\n", report.result.termination.c_str());
}

}  // namespace

void add_modify_command(CLI::App& app) {
  auto args = std::make_shared<ModifyArgs>();
  CLI::App* cmd = app.add_subcommand(
      "modify",
      "Move the nose points of a curve's segments to targets (Lu & Huang 1998): control points, "
      "weights, joining knots, iterated by improvement efficiency");
  cmd->add_option("--model", args->model, "Model (JSON)")->required();
  cmd->add_option("--curve", args->curve, "Name of the curve to modify")->required();
  CLI::Option* targets =
      cmd->add_option("--targets", args->targets, "CSV with header segment,x,y,z (z optional)");
  CLI::Option* points = cmd->add_option("--points", args->points,
                                        "Scan: target = nearest scanned point to each nose point");
  targets->excludes(points);
  points->excludes(targets);
  cmd->add_option("--method", args->method, "points | weights | weights-knots | combined")
      ->check(CLI::IsMember({"points", "weights", "weights-knots", "combined"}))
      ->capture_default_str();
  cmd->add_flag("--iterate", args->iterate,
                "Repeat until the improvement efficiency rho (eq. 22) < --rho-min");
  cmd->add_option("--rho-min", args->rho_min, "Stopping threshold for rho")->capture_default_str();
  cmd->add_option("--max-iterations", args->max_iterations, "Iteration cap")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--nose", args->nose,
                  "Nose point: mean (mean parameter of the segment) or nearest (to its nose "
                  "control point)")
      ->check(CLI::IsMember({"mean", "nearest"}))
      ->capture_default_str();
  cmd->add_option("--out", args->out, "Output model (JSON), the curve replaced")->required();
  cmd->add_option("--report", args->report, "Report (JSON): nose-point errors per step");
  cmd->callback([targets, points, args] {
    if (targets->count() == 0 && points->count() == 0) {
      throw CLI::RequiredError("one of --targets or --points");
    }
    run_modify(*args);
  });
}

}  // namespace nurbsreg::cli
