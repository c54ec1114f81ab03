// align_peers_bench: one synthetic scan of a NURBS model aligned, in the same run, by
//   - nurbsreg: icp::IcpSolver point-to-plane with icp::ModelCorrespondenceFinder (exact closest
//     points and normals on the NURBS surfaces; the model is prepared once, timed separately);
//   - PCL pcl::IterativeClosestPoint (point-to-point) and
//   - PCL pcl::IterativeClosestPointWithNormals (point-to-plane, linear least squares),
//     both against a dense sampling of the model with exact normals (engine::sample_surfaces;
//     the k-d tree over it is built once, timed separately).
// Every method starts from the identity; the scan was made at a known pose 5 degrees / 5 mm
// away, so the final errors are measured against the truth. Wall and CPU time (the process's
// user + system time over all threads) are both reported: on a loaded machine wall time
// includes time spent waiting for a core.
//
//   align_peers_bench [--model FILE] [--points N] [--noise SIGMA] [--dense N] [--threads T]
//                     [--seed S] [--pcl-max-iterations N] [--pcl 0|1|2]
// --pcl: 0 runs nurbsreg only, 1 adds PCL point-to-plane, 2 (default) both PCL methods.
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>
#include <sys/resource.h>
#include <tbb/global_control.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <numbers>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/io/model_file.hpp"

namespace {

using nurbsreg::engine::Vec3;

struct Settings {
  std::string model = NURBSREG_EXAMPLES_DIR "/panel.json";
  std::size_t points = 1000000;
  double noise = 0.01;  // mm, along the normal
  std::size_t dense = 1000000;
  int threads = 2;
  std::uint64_t seed = 1;
  int pcl_max_iterations = 30;
  int pcl = 2;
};

[[noreturn]] void usage(const char* message) {
  std::fprintf(stderr,
               "align_peers_bench: %s\nusage: align_peers_bench [--model FILE] [--points N] "
               "[--noise SIGMA] [--dense N] [--threads T] [--seed S] [--pcl-max-iterations N] "
               "[--pcl 0|1|2]\n",
               message);
  std::exit(2);
}

Settings parse(int argc, char** argv) {
  Settings s;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (i + 1 >= argc) usage(("missing value after " + std::string(arg)).c_str());
    const char* value = argv[++i];
    char* end = nullptr;
    if (arg == "--model") {
      s.model = value;
      continue;
    }
    const double number = std::strtod(value, &end);
    if (end == value || *end != '\0' || !std::isfinite(number) || number < 0) {
      usage(("bad number for " + std::string(arg) + ": " + value).c_str());
    }
    if (arg == "--points") {
      s.points = static_cast<std::size_t>(number);
    } else if (arg == "--noise") {
      s.noise = number;
    } else if (arg == "--dense") {
      s.dense = static_cast<std::size_t>(number);
    } else if (arg == "--threads") {
      s.threads = static_cast<int>(number);
    } else if (arg == "--seed") {
      s.seed = static_cast<std::uint64_t>(number);
    } else if (arg == "--pcl-max-iterations") {
      s.pcl_max_iterations = static_cast<int>(number);
    } else if (arg == "--pcl") {
      s.pcl = static_cast<int>(number);
    } else {
      usage(("unknown option " + std::string(arg)).c_str());
    }
  }
  if (s.points < 10 || s.dense < 10 || s.threads < 1 || s.pcl_max_iterations < 1 || s.pcl > 2) {
    usage(
        "--points and --dense must be >= 10, --threads and --pcl-max-iterations >= 1, --pcl "
        "0, 1 or 2");
  }
  return s;
}

// Wall and process CPU time (all threads, user + system) of a section.
class Stopwatch {
 public:
  Stopwatch() : wall_(std::chrono::steady_clock::now()), cpu_(cpu_seconds()) {}
  double wall() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_).count();
  }
  double cpu() const { return cpu_seconds() - cpu_; }

 private:
  static double cpu_seconds() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
           1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
  }
  std::chrono::steady_clock::time_point wall_;
  double cpu_;
};

struct Outcome {
  std::string method;
  double prepare_wall = 0.0;
  double prepare_cpu = 0.0;
  double wall = 0.0;
  double cpu = 0.0;
  int iterations = 0;
  std::string termination;
  double rotation_deg = 0.0;
  double translation_mm = 0.0;
};

// Error of an estimate against the truth: the rotation angle of T_true * T_est^-1 and the
// displacement it gives the centre of the model's box (a point in the middle of the data,
// so the figure does not grow with the distance of the model from its origin).
void measure(Outcome& o, const Eigen::Isometry3d& T_est, const Eigen::Isometry3d& T_true,
             const Vec3& center) {
  const Eigen::Isometry3d E = T_true * T_est.inverse();
  o.rotation_deg = nurbsreg::icp::rotation_angle(E) * 180.0 / std::numbers::pi;
  o.translation_mm = (E * center - center).norm();
}

Eigen::Isometry3d to_isometry(const Eigen::Matrix4f& m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.matrix() = m.cast<double>();
  // Re-orthonormalise the float rotation (its error, ~1e-7, is far below anything measured).
  T.linear() = nurbsreg::icp::orthonormalize(T.linear());
  return T;
}

// nr_iterations_ is protected in PCL 1.12/1.13: read it through a subclass.
template <class Base>
struct CountingIcp : Base {
  int iterations() const { return this->nr_iterations_; }
};

const char* pcl_state(int state) {
  using Criteria = pcl::registration::DefaultConvergenceCriteria<float>;
  switch (state) {
    case Criteria::CONVERGENCE_CRITERIA_ITERATIONS:
      return "max_iterations";
    case Criteria::CONVERGENCE_CRITERIA_TRANSFORM:
      return "converged (transform eps)";
    case Criteria::CONVERGENCE_CRITERIA_ABS_MSE:
      return "converged (abs MSE)";
    case Criteria::CONVERGENCE_CRITERIA_REL_MSE:
      return "converged (rel MSE)";
    case Criteria::CONVERGENCE_CRITERIA_NO_CORRESPONDENCES:
      return "no correspondences";
    case Criteria::CONVERGENCE_CRITERIA_FAILURE_AFTER_MAX_ITERATIONS:
      return "failed";
    default:
      return "not converged";
  }
}

// PCL settings shared by both PCL methods (see bench/README.md):
//   max correspondence distance 20 mm: above every pair's initial distance (5 degrees over the
//     ~70 mm radius of the panel plus 5 mm), so no inlier is lost at the start, and the scan
//     has no outliers to exclude;
//   transformation epsilon 1e-10 mm^2: stop when the step moves the origin by < 1e-5 mm
//     (PCL compares the squared translation of the increment);
//   rotation epsilon cos(angle) >= 1 - 1e-12 (the float increment's trace reaches 3 once the
//     step rotates by less than ~3e-4 rad, so the translation test decides);
//   euclidean fitness epsilon 1e-6: relative change of the mean squared pair distance.
// These match nurbsreg's tolerances below (1e-6 rad, 1e-5 mm, relative RMS change 1e-6).
template <class Icp>
void configure_pcl(Icp& icp, int max_iterations) {
  icp.setMaxCorrespondenceDistance(20.0);
  icp.setTransformationEpsilon(1e-10);
  icp.setTransformationRotationEpsilon(1.0 - 1e-12);
  icp.setEuclideanFitnessEpsilon(1e-6);
  icp.setMaximumIterations(max_iterations);
}

// The result table (markdown). Errors next to the noise bound (the same scan for every method).
void print_table(const std::vector<Outcome>& outcomes, double bound_rotation_deg,
                 double bound_translation_mm) {
  std::printf(
      "\n| method | prepare wall / CPU (s) | align wall / CPU (s) | iterations | stop | "
      "rotation error (deg) | translation error (mm) | wall ratio | CPU ratio |\n");
  std::printf("| --- | ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: |\n");
  const Outcome& ours = outcomes.front();
  for (const Outcome& o : outcomes) {
    std::printf("| %s | %.2f / %.2f | %.3f / %.3f | %d | %s | %.2e | %.2e | %.2fx | %.2fx |\n",
                o.method.c_str(), o.prepare_wall, o.prepare_cpu, o.wall, o.cpu, o.iterations,
                o.termination.c_str(), o.rotation_deg, o.translation_mm, o.wall / ours.wall,
                o.cpu / ours.cpu);
  }
  std::printf("| noise bound (1-sigma RMS, from the final Hessian) | | | | | %.2e | %.2e | | |\n",
              bound_rotation_deg, bound_translation_mm);
  std::printf(
      "\nratios: time of the method / time of nurbsreg (align only). Error ratios vs "
      "nurbsreg:");
  for (std::size_t i = 1; i < outcomes.size(); ++i) {
    std::printf(" %s rotation %.1fx, translation %.1fx;", outcomes[i].method.c_str(),
                outcomes[i].rotation_deg / ours.rotation_deg,
                outcomes[i].translation_mm / ours.translation_mm);
  }
  std::printf("\n");
}

}  // namespace

int main(int argc, char** argv) try {
  const Settings settings = parse(argc, argv);
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // progress visible when redirected
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, settings.threads);
  namespace engine = nurbsreg::engine;
  namespace icp = nurbsreg::icp;

  const engine::Model model = nurbsreg::io::read_model_file(settings.model);
  engine::Aabb box;
  for (const engine::NurbsSurface& s : model.surfaces) {
    for (const Vec3& p : s.control_points)
      box.extend(p);
  }
  const Vec3 center = 0.5 * (box.lo + box.hi);

  // The scan: 5 degrees about a generic axis and 5 mm away from the model frame.
  engine::SyntheticScanOptions so;
  so.points = settings.points;
  so.noise_sigma = settings.noise;
  so.seed = settings.seed;
  Eigen::Isometry3d T_true = Eigen::Isometry3d::Identity();  // model = T_true * scan
  T_true.linear() =
      Eigen::AngleAxisd(5.0 * std::numbers::pi / 180.0, Vec3(1, 2, 3).normalized()).matrix();
  T_true.translation() = Vec3(3.0, -2.0, 4.0).normalized() * 5.0;
  so.T_scan_model = T_true.inverse();
  const engine::SyntheticScan scan = engine::make_synthetic_scan(model, so);
  std::printf("model %s: %zu surfaces, box diagonal %.1f mm, area %.0f mm^2\n",
              settings.model.c_str(), model.surfaces.size(), box.diagonal(),
              engine::surface_area(model));
  std::printf(
      "scan: %zu points, noise sigma %.4g mm along the normal, start 5 deg / 5 mm off; "
      "%d TBB threads\n",
      scan.points.size(), settings.noise, settings.threads);

  std::vector<Outcome> outcomes;

  // --- nurbsreg ---------------------------------------------------------------------------
  // The model is prepared once (Bezier decomposition, cached coefficients, hierarchy); then the
  // same scan is aligned three times: with the default schedule (automatic coarse-to-fine:
  // nested deterministic subsamples of 1% and 10% of the scan, each left when its step is below
  // its own noise level or predicted to be, then all points until the step is below tolerance),
  // the same with predict_final_convergence (the last stage also ends on a predicted step:
  // one full-resolution pass), and on all points from the first iteration without statistical
  // or predicted stops (the plain loop).
  Stopwatch prep;
  const engine::PreparedModel prepared{engine::Model(model)};
  const double prepare_wall = prep.wall();
  const double prepare_cpu = prep.cpu();
  // 1-sigma of the pose error the noise alone allows (the Cramer-Rao-like bound
  // sigma sqrt(diag H^-1) from the final Hessian, IcpResult::covariance), as RMS rotation angle
  // and RMS displacement of the box centre (the point where the errors are measured).
  double bound_rotation_deg = 0.0;
  double bound_translation_mm = 0.0;
  enum class Mode { plain, schedule, schedule_predicted };
  const auto run_nurbsreg = [&](const char* label, Mode mode) {
    Outcome o;
    o.method = label;
    o.prepare_wall = prepare_wall;
    o.prepare_cpu = prepare_cpu;
    icp::ModelCorrespondenceFinder finder(prepared);
    icp::IcpOptions options;
    options.method = icp::IcpMethod::point_to_plane;
    options.max_iterations = 50;
    options.max_correspondence_distance = 20.0;
    options.rotation_tolerance = 1e-6;
    options.translation_tolerance = 1e-5;
    options.relative_rms_tolerance = 1e-6;
    options.predict_final_convergence = mode == Mode::schedule_predicted;
    if (mode == Mode::plain) {
      options.auto_coarse = false;
      options.predict_convergence = false;
      options.statistical_tolerance = 0.0;
    }
    icp::IcpSolver solver(options);
    Stopwatch run;
    const icp::IcpResult r = solver.align(finder, scan.points, Eigen::Isometry3d::Identity());
    o.wall = run.wall();
    o.cpu = run.cpu();
    o.iterations = r.iterations;
    o.termination = std::string(icp::to_string(r.termination));
    measure(o, r.T_model_scan, T_true, center);
    std::printf("%s: %s\n", label, r.brief_report().c_str());
    for (const icp::IcpIteration& it : r.log) {
      std::printf(
          "  stage %d: %zu points, %zu inliers, rms %.4g, step %.2e rad / %.2e mm / %.3g sigma%s, "
          "%.3f s\n",
          it.stage, it.points, it.inliers, it.rms, it.rotation_step, it.translation_step,
          it.step_sigmas, it.predicted ? " (next predicted below tolerance)" : "", it.seconds);
    }
    // Projection work of the last (full, warm-started) correspondence step.
    const engine::ProjectionCounters& c = finder.last_counters();
    std::printf("  last projection: %.2f patches visited per point (49-patch panel)\n",
                static_cast<double>(c.patches_visited) / static_cast<double>(c.points));
    // Covariance of the left twist (omega, v) about the model origin: the displacement of the
    // centre is v + omega x center = [-[center]x, I] xi.
    Eigen::Matrix<double, 3, 6> A;
    A << -icp::skew(center), Eigen::Matrix3d::Identity();
    bound_rotation_deg =
        std::sqrt(r.covariance.topLeftCorner<3, 3>().trace()) * 180.0 / std::numbers::pi;
    bound_translation_mm = std::sqrt((A * r.covariance * A.transpose()).trace());
    std::printf("  noise bound (1-sigma RMS): rotation %.3g deg, translation %.3g mm (centre)\n",
                bound_rotation_deg, bound_translation_mm);
    outcomes.push_back(o);
  };
  run_nurbsreg("nurbsreg point-to-plane, exact NURBS, default schedule", Mode::schedule);
  run_nurbsreg("nurbsreg, default schedule + predict_final_convergence", Mode::schedule_predicted);
  run_nurbsreg("nurbsreg, all points every iteration", Mode::plain);
  if (settings.pcl == 0) {
    print_table(outcomes, bound_rotation_deg, bound_translation_mm);
    return 0;
  }

  // --- PCL: dense sampling with exact normals ------------------------------------------------
  Stopwatch sampling;
  const std::vector<engine::SurfaceSample> dense =
      engine::sample_surfaces(model, settings.dense, settings.seed + 1000);
  auto target = pcl::make_shared<pcl::PointCloud<pcl::PointNormal>>();
  auto target_xyz = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  target->resize(dense.size());
  target_xyz->resize(dense.size());
  for (std::size_t i = 0; i < dense.size(); ++i) {
    const Vec3 p = dense[i].point;
    const Vec3 n = dense[i].normal;
    pcl::PointNormal& q = (*target)[i];
    q.x = static_cast<float>(p.x());
    q.y = static_cast<float>(p.y());
    q.z = static_cast<float>(p.z());
    q.normal_x = static_cast<float>(n.x());
    q.normal_y = static_cast<float>(n.y());
    q.normal_z = static_cast<float>(n.z());
    (*target_xyz)[i] = pcl::PointXYZ(q.x, q.y, q.z);
  }
  // Source normals: the exact ones of the scan's source samples, moved into the scan frame.
  // PCL's (asymmetric) point-to-plane objective uses only the target normals.
  auto source = pcl::make_shared<pcl::PointCloud<pcl::PointNormal>>();
  auto source_xyz = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  source->resize(scan.points.size());
  source_xyz->resize(scan.points.size());
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    const Vec3 p = scan.points[i];
    const Vec3 n = scan.surface[i] < 0
                       ? Vec3::Zero()
                       : Vec3(so.T_scan_model.linear() *
                              engine::surface_normal(model.surfaces[scan.surface[i]],
                                                     scan.uv[i].x(), scan.uv[i].y()));
    pcl::PointNormal& q = (*source)[i];
    q.x = static_cast<float>(p.x());
    q.y = static_cast<float>(p.y());
    q.z = static_cast<float>(p.z());
    q.normal_x = static_cast<float>(n.x());
    q.normal_y = static_cast<float>(n.y());
    q.normal_z = static_cast<float>(n.z());
    (*source_xyz)[i] = pcl::PointXYZ(q.x, q.y, q.z);
  }
  std::printf(
      "PCL target: %zu samples with exact normals (spacing ~%.3f mm), made in %.2f s "
      "(not counted)\n",
      dense.size(), std::sqrt(engine::surface_area(model) / double(dense.size())), sampling.wall());

  // One PCL method: kd-tree on the target (prepare), then align from the identity (run).
  auto run_pcl = [&](const char* method, auto icp, const auto& source_cloud,
                     const auto& target_cloud) {
    using Point = typename std::decay_t<decltype(*target_cloud)>::PointType;
    Outcome o;
    o.method = method;
    Stopwatch prep;
    auto tree = pcl::make_shared<pcl::search::KdTree<Point>>();
    tree->setInputCloud(target_cloud);
    o.prepare_wall = prep.wall();
    o.prepare_cpu = prep.cpu();
    configure_pcl(icp, settings.pcl_max_iterations);
    icp.setInputSource(source_cloud);
    icp.setInputTarget(target_cloud);
    icp.setSearchMethodTarget(tree, true);
    pcl::PointCloud<Point> aligned;
    Stopwatch run;
    icp.align(aligned);
    o.wall = run.wall();
    o.cpu = run.cpu();
    o.iterations = icp.iterations();
    o.termination = pcl_state(icp.getConvergeCriteria()->getConvergenceState());
    measure(o, to_isometry(icp.getFinalTransformation()), T_true, center);
    outcomes.push_back(o);
  };
  if (settings.pcl >= 2) {
    run_pcl("PCL IterativeClosestPoint (point-to-point)",
            CountingIcp<pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>>{}, source_xyz,
            target_xyz);
  }
  run_pcl("PCL IterativeClosestPointWithNormals (point-to-plane)",
          CountingIcp<pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal>>{},
          source, target);

  print_table(outcomes, bound_rotation_deg, bound_translation_mm);
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "align_peers_bench: %s\n", e.what());
  return 1;
}
