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
// With --seeds N > 1 the same is done on N scans (seeds S, S+1, ...: new noise and new sample
// positions, the same pose) and a summary over the seeds follows: mean / max time, RMS / max
// error next to the mean noise bound, and a verdict (more accurate? at the noise level?). One
// scan cannot answer that: a single noise draw may favour either method.
//
//   align_peers_bench [--model FILE] [--points N] [--noise SIGMA] [--dense N] [--threads T]
//                     [--seed S] [--seeds N] [--nurbsreg-variants all|default]
//                     [--pcl-max-iterations N] [--pcl 0|1|2] [--reuse 0|1]
// --pcl: 0 runs nurbsreg only, 1 adds PCL point-to-plane, 2 (default) both PCL methods.
// --nurbsreg-variants: all (default when --seeds is 1) runs the three nurbsreg rows, default
// (default when --seeds > 1) only the default schedule.
// With --seeds > 1 the exit status is 1 when nurbsreg's RMS error exceeds 3 noise bounds (a
// broken alignment; an N-seed RMS of a Gaussian error that far out is vanishingly unlikely).
// --reuse 1 aligns the seeds' scans frame after frame with ONE IcpSolver and ONE finder for the
// default schedule (as an inspection line or a tracker would): the first frame pays the first
// touch of the per-point arrays (~300 MB for 1 M points), the later ones reuse them. Each frame
// still starts from the identity with no hints (align() resets the finder). 0 (default): a fresh
// solver and finder per scan, so every row includes that first touch.
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>
#include <sys/resource.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "support/source_paths.hpp"

namespace {

using nurbsreg::engine::Vec3;

// Which nurbsreg rows run on each scan.
enum class Variants { unset, all, default_schedule };

struct Settings {
  std::string model = nurbsreg::test::examples_dir() + "/panel.json";
  std::size_t points = 1000000;
  double noise = 0.01;  // mm, along the normal
  std::size_t dense = 1000000;
  int threads = 2;
  std::uint64_t seed = 1;
  std::size_t seeds = 1;
  Variants variants = Variants::unset;
  int pcl_max_iterations = 30;
  int pcl = 2;
  bool reuse = false;
};

[[noreturn]] void usage(const char* message) {
  std::fprintf(
      stderr,
      "align_peers_bench: %s\nusage: align_peers_bench [--model FILE] [--points N] "
      "[--noise SIGMA] [--dense N] [--threads T] [--seed S] [--seeds N] "
      "[--nurbsreg-variants all|default] [--pcl-max-iterations N] [--pcl 0|1|2] [--reuse 0|1]\n",
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
    if (arg == "--nurbsreg-variants") {
      const std::string_view v = value;
      if (v == "all") {
        s.variants = Variants::all;
      } else if (v == "default") {
        s.variants = Variants::default_schedule;
      } else {
        usage(("--nurbsreg-variants must be all or default, not " + std::string(v)).c_str());
      }
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
    } else if (arg == "--seeds") {
      s.seeds = static_cast<std::size_t>(number);
    } else if (arg == "--pcl-max-iterations") {
      s.pcl_max_iterations = static_cast<int>(number);
    } else if (arg == "--pcl") {
      s.pcl = static_cast<int>(number);
    } else if (arg == "--reuse") {
      if (number != 0 && number != 1) usage("--reuse must be 0 or 1");
      s.reuse = number == 1;
    } else {
      usage(("unknown option " + std::string(arg)).c_str());
    }
  }
  if (s.points < 10 || s.dense < 10 || s.threads < 1 || s.pcl_max_iterations < 1 || s.pcl > 2 ||
      s.seeds < 1) {
    usage(
        "--points and --dense must be >= 10, --threads, --seeds and --pcl-max-iterations >= 1, "
        "--pcl 0, 1 or 2");
  }
  if (s.variants == Variants::unset) {
    s.variants = s.seeds == 1 ? Variants::all : Variants::default_schedule;
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
  // The same errors as vectors (rotation vector in degrees, displacement of the centre), so
  // two methods' estimates on the same scan can be compared with each other.
  Vec3 rotation_vector_deg = Vec3::Zero();
  Vec3 displacement_mm = Vec3::Zero();
};

// 1-sigma (RMS) pose error the noise alone allows on one scan.
struct NoiseBound {
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
  o.displacement_mm = E * center - center;
  o.translation_mm = o.displacement_mm.norm();
  const Eigen::AngleAxisd aa(E.linear());
  o.rotation_vector_deg = aa.axis() * (aa.angle() * 180.0 / std::numbers::pi);
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

// A point set as the two PCL clouds the methods take: with normals (point-to-plane) and
// without (point-to-point).
struct PclClouds {
  pcl::PointCloud<pcl::PointNormal>::Ptr with_normals =
      pcl::make_shared<pcl::PointCloud<pcl::PointNormal>>();
  pcl::PointCloud<pcl::PointXYZ>::Ptr xyz = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();

  explicit PclClouds(std::size_t n) {
    with_normals->resize(n);
    xyz->resize(n);
  }
  void set(std::size_t i, const Vec3& p, const Vec3& n) {
    pcl::PointNormal& q = (*with_normals)[i];
    q.x = static_cast<float>(p.x());
    q.y = static_cast<float>(p.y());
    q.z = static_cast<float>(p.z());
    q.normal_x = static_cast<float>(n.x());
    q.normal_y = static_cast<float>(n.y());
    q.normal_z = static_cast<float>(n.z());
    (*xyz)[i] = pcl::PointXYZ(q.x, q.y, q.z);
  }
};

// The k-d tree over PCL's target, built once per method and reused for every scan (PCL does
// not rebuild a search method given with force_no_recompute).
template <class Point>
struct PclTree {
  typename pcl::search::KdTree<Point>::Ptr tree;
  double wall = 0.0;
  double cpu = 0.0;
};

// The result table of one scan (markdown). Errors next to the noise bound (the same scan for
// every method).
void print_table(const std::vector<Outcome>& outcomes, const NoiseBound& bound) {
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
              bound.rotation_deg, bound.translation_mm);
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

// One method over all seeds.
struct MethodSummary {
  std::string method;
  double wall_mean = 0.0;
  double wall_max = 0.0;
  double cpu_mean = 0.0;
  double cpu_max = 0.0;
  double iterations_mean = 0.0;
  double rotation_rms = 0.0;  // sqrt(mean over seeds of the squared error)
  double rotation_max = 0.0;
  double translation_rms = 0.0;
  double translation_max = 0.0;
  // RMS over seeds of the difference between this method's estimate and nurbsreg's (default
  // schedule) on the same scan: the part of the error that is not the shared noise draw.
  double rotation_vs_ours_rms = 0.0;
  double translation_vs_ours_rms = 0.0;
};

// runs[seed][method]; method 0 is nurbsreg's default schedule.
MethodSummary summarize(const std::vector<std::vector<Outcome>>& runs, std::size_t method) {
  MethodSummary s;
  s.method = runs.front()[method].method;
  for (const std::vector<Outcome>& seed : runs) {
    const Outcome& o = seed[method];
    const Outcome& ours = seed.front();
    s.wall_mean += o.wall;
    s.wall_max = std::max(s.wall_max, o.wall);
    s.cpu_mean += o.cpu;
    s.cpu_max = std::max(s.cpu_max, o.cpu);
    s.iterations_mean += o.iterations;
    s.rotation_rms += o.rotation_deg * o.rotation_deg;
    s.rotation_max = std::max(s.rotation_max, o.rotation_deg);
    s.translation_rms += o.translation_mm * o.translation_mm;
    s.translation_max = std::max(s.translation_max, o.translation_mm);
    s.rotation_vs_ours_rms += (o.rotation_vector_deg - ours.rotation_vector_deg).squaredNorm();
    s.translation_vs_ours_rms += (o.displacement_mm - ours.displacement_mm).squaredNorm();
  }
  const double n = static_cast<double>(runs.size());
  s.wall_mean /= n;
  s.cpu_mean /= n;
  s.iterations_mean /= n;
  s.rotation_rms = std::sqrt(s.rotation_rms / n);
  s.translation_rms = std::sqrt(s.translation_rms / n);
  s.rotation_vs_ours_rms = std::sqrt(s.rotation_vs_ours_rms / n);
  s.translation_vs_ours_rms = std::sqrt(s.translation_vs_ours_rms / n);
  return s;
}

// The summary table over the seeds and the verdict. Returns false when nurbsreg's own RMS error
// is beyond 3 noise bounds (a broken alignment, not bad luck: see the header comment).
bool print_summary(const std::vector<std::vector<Outcome>>& runs,
                   const std::vector<NoiseBound>& bounds, std::uint64_t first_seed) {
  const std::size_t n = runs.size();
  NoiseBound bound;  // mean over the seeds
  for (const NoiseBound& b : bounds) {
    bound.rotation_deg += b.rotation_deg / static_cast<double>(n);
    bound.translation_mm += b.translation_mm / static_cast<double>(n);
  }
  std::vector<MethodSummary> summaries;
  for (std::size_t m = 0; m < runs.front().size(); ++m)
    summaries.push_back(summarize(runs, m));
  const MethodSummary& ours = summaries.front();

  std::printf(
      "\nsummary over %zu seeds (%llu..%llu; each seed its own scan, the same pose; RMS and max "
      "over the seeds; ratios: method / nurbsreg default schedule):\n",
      n, static_cast<unsigned long long>(first_seed),
      static_cast<unsigned long long>(first_seed + n - 1));
  std::printf(
      "\n| method | align wall mean / max (s) | align CPU mean / max (s) | mean iterations | "
      "rotation error RMS / max (deg) | translation error RMS / max (mm) | RMS / noise bound "
      "(rotation, translation) | RMS error ratio (rotation, translation) | wall / CPU ratio "
      "(means) |\n");
  std::printf("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
  for (const MethodSummary& s : summaries) {
    std::printf(
        "| %s | %.3f / %.3f | %.3f / %.3f | %.1f | %.2e / %.2e | %.2e / %.2e | %.2f, %.2f | "
        "%.2fx, %.2fx | %.2fx / %.2fx |\n",
        s.method.c_str(), s.wall_mean, s.wall_max, s.cpu_mean, s.cpu_max, s.iterations_mean,
        s.rotation_rms, s.rotation_max, s.translation_rms, s.translation_max,
        s.rotation_rms / bound.rotation_deg, s.translation_rms / bound.translation_mm,
        s.rotation_rms / ours.rotation_rms, s.translation_rms / ours.translation_rms,
        s.wall_mean / ours.wall_mean, s.cpu_mean / ours.cpu_mean);
  }
  std::printf(
      "| noise bound (1-sigma RMS from nurbsreg's final Hessian, mean over seeds) | | | | %.2e | "
      "%.2e | 1, 1 | | |\n",
      bound.rotation_deg, bound.translation_mm);

  // For an isotropic 3-D Gaussian error, the squared RMS over n seeds is a chi-square with 3n
  // degrees of freedom scaled by 1/(3n): its square root has a relative standard error of
  // ~1/sqrt(6n). Differences between RMS values well inside twice that are not significant
  // (a conservative yardstick: the methods see the same scans, so their errors are correlated).
  const double spread = 1.0 / std::sqrt(6.0 * static_cast<double>(n));
  std::printf(
      "\nverdict (%zu seeds; an RMS over %zu seeds is uncertain by ~%.0f%% (1 sigma), so ratios "
      "within 1 +- %.0f%% are not significant):\n",
      n, n, 100.0 * spread, 200.0 * spread);
  for (const MethodSummary& s : summaries) {
    std::printf(
        "  error at the noise level: %s RMS / noise bound = %.2f (rotation), %.2f "
        "(translation)\n",
        s.method.c_str(), s.rotation_rms / bound.rotation_deg,
        s.translation_rms / bound.translation_mm);
  }
  for (std::size_t m = 1; m < summaries.size(); ++m) {
    const MethodSummary& s = summaries[m];
    if (s.method.rfind("PCL", 0) != 0) continue;
    const double rotation_ratio = s.rotation_rms / ours.rotation_rms;
    const double translation_ratio = s.translation_rms / ours.translation_rms;
    const bool more_accurate = rotation_ratio > 1.0 && translation_ratio > 1.0;
    const char* significance =
        more_accurate
            ? (rotation_ratio > 1.0 + 2.0 * spread && translation_ratio > 1.0 + 2.0 * spread
                   ? "beyond the seed-to-seed spread"
                   : "NOT significant: within the seed-to-seed spread")
            : (rotation_ratio < 1.0 - 2.0 * spread && translation_ratio < 1.0 - 2.0 * spread
                   ? "PCL more accurate beyond the seed-to-seed spread"
                   : "within the seed-to-seed spread or mixed");
    std::printf(
        "  vs %s: nurbsreg more accurate: %s (rotation RMS %.2e vs %.2e deg, translation RMS "
        "%.2e vs %.2e mm; %s)\n",
        s.method.c_str(), more_accurate ? "yes" : "no", ours.rotation_rms, s.rotation_rms,
        ours.translation_rms, s.translation_rms, significance);
    std::printf(
        "  vs %s: its pose minus nurbsreg's on the same scan, RMS %.2e deg / %.2e mm = %.2f / "
        "%.2f noise bounds (the error beyond the shared noise draw)\n",
        s.method.c_str(), s.rotation_vs_ours_rms, s.translation_vs_ours_rms,
        s.rotation_vs_ours_rms / bound.rotation_deg,
        s.translation_vs_ours_rms / bound.translation_mm);
    std::printf(
        "  vs %s: nurbsreg >= 3x faster: %s (mean CPU %.3f vs %.3f s = %.2fx; mean wall %.3f vs "
        "%.3f s = %.2fx)\n",
        s.method.c_str(), s.cpu_mean >= 3.0 * ours.cpu_mean ? "yes" : "no", ours.cpu_mean,
        s.cpu_mean, s.cpu_mean / ours.cpu_mean, ours.wall_mean, s.wall_mean,
        s.wall_mean / ours.wall_mean);
  }
  // The 1e-9 slack keeps a noise-free scan (bound 0, error at rounding level) from failing.
  const bool sane = ours.rotation_rms <= 3.0 * bound.rotation_deg + 1e-9 &&
                    ours.translation_rms <= 3.0 * bound.translation_mm + 1e-9;
  if (!sane) {
    std::printf("FAILED: nurbsreg's RMS error is beyond 3 noise bounds\n");
  }
  return sane;
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

  // The scans: 5 degrees about a generic axis and 5 mm away from the model frame.
  engine::SyntheticScanOptions so;
  so.points = settings.points;
  so.noise_sigma = settings.noise;
  Eigen::Isometry3d T_true = Eigen::Isometry3d::Identity();  // model = T_true * scan
  T_true.linear() =
      Eigen::AngleAxisd(5.0 * std::numbers::pi / 180.0, Vec3(1, 2, 3).normalized()).matrix();
  T_true.translation() = Vec3(3.0, -2.0, 4.0).normalized() * 5.0;
  so.T_scan_model = T_true.inverse();

  // --- nurbsreg ---------------------------------------------------------------------------
  // The model is prepared once (Bezier decomposition, cached coefficients, hierarchy); then each
  // scan is aligned with the default schedule (automatic coarse-to-fine: nested deterministic
  // subsamples of 1% and 10% of the scan, each left when its step is below its own noise level
  // or predicted to be, then all points until the step is below tolerance) and, with
  // --nurbsreg-variants all, also with predict_final_convergence (the last stage also ends on a
  // predicted step: one full-resolution pass) and on all points from the first iteration
  // without statistical or predicted stops (the plain loop).
  Stopwatch prep;
  const engine::PreparedModel prepared{engine::Model(model)};
  const double prepare_wall = prep.wall();
  const double prepare_cpu = prep.cpu();
  enum class Mode { plain, schedule, schedule_predicted };
  std::optional<icp::ModelCorrespondenceFinder> reused_finder;
  std::optional<icp::IcpSolver> reused_solver;
  // Aligns `points`; fills `bound` from the run's covariance when it is given.
  const auto run_nurbsreg = [&](const char* label, Mode mode, const std::vector<Vec3>& points,
                                NoiseBound* bound) {
    Outcome o;
    o.method = label;
    o.prepare_wall = prepare_wall;
    o.prepare_cpu = prepare_cpu;
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
    // --reuse: the default schedule's solver and finder live across the scans (frames).
    const bool reuse = settings.reuse && mode == Mode::schedule;
    std::optional<icp::ModelCorrespondenceFinder> own_finder;
    std::optional<icp::IcpSolver> own_solver;
    if (!reuse || !reused_solver) {
      (reuse ? reused_finder : own_finder).emplace(prepared);
      (reuse ? reused_solver : own_solver).emplace(options);
    }
    icp::ModelCorrespondenceFinder& finder = reuse ? *reused_finder : *own_finder;
    icp::IcpSolver& solver = reuse ? *reused_solver : *own_solver;
    Stopwatch run;
    const icp::IcpResult r = solver.align(finder, points, Eigen::Isometry3d::Identity());
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
    // 1-sigma of the pose error the noise alone allows (the Cramer-Rao-like bound
    // sigma sqrt(diag H^-1) from the final Hessian, IcpResult::covariance), as RMS rotation
    // angle and RMS displacement of the box centre (the point where the errors are measured).
    // Covariance of the left twist (omega, v) about the model origin: the displacement of the
    // centre is v + omega x center = [-[center]x, I] xi.
    Eigen::Matrix<double, 3, 6> A;
    A << -icp::skew(center), Eigen::Matrix3d::Identity();
    const double bound_rotation_deg =
        std::sqrt(r.covariance.topLeftCorner<3, 3>().trace()) * 180.0 / std::numbers::pi;
    const double bound_translation_mm = std::sqrt((A * r.covariance * A.transpose()).trace());
    std::printf("  noise bound (1-sigma RMS): rotation %.3g deg, translation %.3g mm (centre)\n",
                bound_rotation_deg, bound_translation_mm);
    if (bound != nullptr) *bound = {bound_rotation_deg, bound_translation_mm};
    return o;
  };

  // --- PCL: dense sampling with exact normals, built once (it does not depend on the scan) --
  std::unique_ptr<PclClouds> target;
  PclTree<pcl::PointXYZ> tree_xyz;
  PclTree<pcl::PointNormal> tree_normals;
  const auto make_target = [&] {
    Stopwatch sampling;
    const std::vector<engine::SurfaceSample> dense =
        engine::sample_surfaces(model, settings.dense, settings.seed + 1000);
    target = std::make_unique<PclClouds>(dense.size());
    for (std::size_t i = 0; i < dense.size(); ++i)
      target->set(i, dense[i].point, dense[i].normal);
    std::printf(
        "PCL target: %zu samples with exact normals (spacing ~%.3f mm), made in %.2f s "
        "(not counted)\n",
        dense.size(), std::sqrt(engine::surface_area(model) / double(dense.size())),
        sampling.wall());
  };
  // One PCL method: k-d tree on the target (prepare, first use only), then align from the
  // identity (run).
  const auto run_pcl = [&](const char* method, auto icp, const auto& source_cloud,
                           const auto& target_cloud, auto& tree) {
    using Point = typename std::decay_t<decltype(*target_cloud)>::PointType;
    Outcome o;
    o.method = method;
    if (!tree.tree) {
      Stopwatch build;
      tree.tree = pcl::make_shared<pcl::search::KdTree<Point>>();
      tree.tree->setInputCloud(target_cloud);
      tree.wall = build.wall();
      tree.cpu = build.cpu();
    }
    o.prepare_wall = tree.wall;
    o.prepare_cpu = tree.cpu;
    configure_pcl(icp, settings.pcl_max_iterations);
    icp.setInputSource(source_cloud);
    icp.setInputTarget(target_cloud);
    icp.setSearchMethodTarget(tree.tree, true);
    pcl::PointCloud<Point> aligned;
    Stopwatch run;
    icp.align(aligned);
    o.wall = run.wall();
    o.cpu = run.cpu();
    o.iterations = icp.iterations();
    o.termination = pcl_state(icp.getConvergeCriteria()->getConvergenceState());
    measure(o, to_isometry(icp.getFinalTransformation()), T_true, center);
    return o;
  };

  std::vector<std::vector<Outcome>> runs;  // [seed][method]
  std::vector<NoiseBound> bounds;          // [seed], from the default schedule
  for (std::size_t k = 0; k < settings.seeds; ++k) {
    so.seed = settings.seed + k;
    const engine::SyntheticScan scan = engine::make_synthetic_scan(model, so);
    if (settings.seeds > 1) {
      std::printf("\n=== seed %llu (%zu of %zu) ===\n", static_cast<unsigned long long>(so.seed),
                  k + 1, settings.seeds);
    }
    if (k == 0) {
      std::printf("model %s: %zu surfaces, box diagonal %.1f mm, area %.0f mm^2\n",
                  settings.model.c_str(), model.surfaces.size(), box.diagonal(),
                  engine::surface_area(model));
    }
    std::printf(
        "scan: %zu points, noise sigma %.4g mm along the normal, start 5 deg / 5 mm off; "
        "%d TBB threads\n",
        scan.points.size(), settings.noise, settings.threads);

    std::vector<Outcome> outcomes;
    NoiseBound bound;
    outcomes.push_back(run_nurbsreg("nurbsreg point-to-plane, exact NURBS, default schedule",
                                    Mode::schedule, scan.points, &bound));
    if (settings.variants == Variants::all) {
      outcomes.push_back(run_nurbsreg("nurbsreg, default schedule + predict_final_convergence",
                                      Mode::schedule_predicted, scan.points, nullptr));
      outcomes.push_back(
          run_nurbsreg("nurbsreg, all points every iteration", Mode::plain, scan.points, nullptr));
    }
    if (settings.pcl > 0) {
      if (!target) make_target();
      // Source normals: the exact ones of the scan's source samples, moved into the scan frame.
      // PCL's (asymmetric) point-to-plane objective uses only the target normals.
      PclClouds source(scan.points.size());
      for (std::size_t i = 0; i < scan.points.size(); ++i) {
        const Vec3 n = scan.surface[i] < 0
                           ? Vec3::Zero()
                           : Vec3(so.T_scan_model.linear() *
                                  engine::surface_normal(model.surfaces[scan.surface[i]],
                                                         scan.uv[i].x(), scan.uv[i].y()));
        source.set(i, scan.points[i], n);
      }
      if (settings.pcl >= 2) {
        outcomes.push_back(
            run_pcl("PCL IterativeClosestPoint (point-to-point)",
                    CountingIcp<pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>>{},
                    source.xyz, target->xyz, tree_xyz));
      }
      outcomes.push_back(run_pcl(
          "PCL IterativeClosestPointWithNormals (point-to-plane)",
          CountingIcp<pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal>>{},
          source.with_normals, target->with_normals, tree_normals));
    }
    print_table(outcomes, bound);
    runs.push_back(std::move(outcomes));
    bounds.push_back(bound);
  }
  if (settings.seeds > 1 && !print_summary(runs, bounds, settings.seed)) return 1;
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "align_peers_bench: %s\n", e.what());
  return 1;
}
