// `nurbsreg synth`: a synthetic scan of a model (CONTRACT.md §1), for demos, tests and benchmarks.

#include <spdlog/spdlog.h>

#include <sstream>

#include "commands.hpp"
#include "common.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/pose.hpp"

namespace nurbsreg::cli {
namespace {

struct SynthArgs {
  std::string model;
  std::size_t points = 0;
  std::string out;
  double noise = 0.0;
  std::string pose;
  std::uint64_t seed = 1;
  std::string out_pose;
  double outliers = 0.0;
  double fixture = 0.0;
  std::string fixture_up = "0 0 1";
  double view_fraction = 1.0;
  std::string view_direction = "0 0 1";
};

std::vector<double> parse_numbers(const std::string& option, const std::string& text,
                                  std::size_t expected) {
  std::istringstream in(text);
  std::vector<double> values;
  double x = 0.0;
  while (in >> x)
    values.push_back(x);
  if (!in.eof() || values.size() != expected) {
    throw UsageError(option + ": expected " + std::to_string(expected) +
                     " numbers separated by spaces, got \"" + text + "\"");
  }
  return values;
}

void run_synth(const SynthArgs& args) {
  const engine::Model model = load_model_file(args.model);
  if (model.surfaces.empty()) throw UsageError(args.model + ": synth needs a model with surfaces");
  engine::SyntheticScanOptions options;
  options.points = args.points;
  options.noise_sigma = args.noise;
  options.seed = args.seed;
  options.outlier_fraction = args.outliers;
  options.fixture_fraction = args.fixture;
  const auto up = parse_numbers("--fixture-up", args.fixture_up, 3);
  options.fixture_up = engine::Vec3(up[0], up[1], up[2]);
  options.view_fraction = args.view_fraction;
  const auto dir = parse_numbers("--view-direction", args.view_direction, 3);
  options.view_direction = engine::Vec3(dir[0], dir[1], dir[2]);
  if (!args.pose.empty()) {
    const auto p = parse_numbers("--pose", args.pose, 6);
    options.T_scan_model =
        engine::pose_from_euler_degrees(p[0], p[1], p[2], engine::Vec3(p[3], p[4], p[5]));
  }
  if (auto error = options.validate()) throw UsageError(*error);
  const Stopwatch watch;
  const engine::SyntheticScan scan = engine::make_synthetic_scan(model, options);
  io::write_point_cloud(args.out, scan.points);
  if (!args.out_pose.empty()) io::write_pose(args.out_pose, scan.T_model_scan.matrix());
  spdlog::info(
      "{}: {} points (noise {}, outliers {:.1f}%, fixture {:.1f}%, view {:.0f}%) in {:.2f} s",
      args.out, scan.points.size(), args.noise, 100.0 * args.outliers, 100.0 * args.fixture,
      100.0 * args.view_fraction, watch.seconds());
}

}  // namespace

void add_synth_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("synth", "A synthetic scan of the model (area-uniform samples)");
  auto args = std::make_shared<SynthArgs>();
  cmd->add_option("--model", args->model, "Model file (.json, .step/.stp, .iges/.igs)")->required();
  cmd->add_option("--points", args->points, "Number of points")
      ->required()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--out", args->out, "Scan file: .pcd (binary), .ply or .xyz")->required();
  cmd->add_option("--noise", args->noise, "Gaussian noise sigma along the normal (model units)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--pose", args->pose,
                  "Scanner pose \"rx ry rz tx ty tz\": degrees about x, y, z, then translation; "
                  "scan_point = pose * model_point");
  cmd->add_option("--seed", args->seed, "Random seed (same seed, same scan)");
  cmd->add_option("--out-pose", args->out_pose,
                  "Write the pose that maps the scan back onto the model (T_model_scan)");
  cmd->add_option("--outliers", args->outliers,
                  "Fraction of points replaced by outliers, uniform in the scan's box")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--fixture", args->fixture,
                  "Fraction of points replaced by a fixture plane under the part (clustered "
                  "clutter; with --outliers at most 1 in all)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--fixture-up", args->fixture_up,
                  "\"x y z\": the model's up direction; the fixture lies below the part along it");
  cmd->add_option("--view-fraction", args->view_fraction,
                  "Partial view: keep this fraction of the model, seen from --view-direction")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--view-direction", args->view_direction, "\"x y z\" for --view-fraction");
  cmd->callback([args] { run_synth(*args); });
}

}  // namespace nurbsreg::cli
