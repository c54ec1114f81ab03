// The global coarse stage (DESIGN.md "From any pose to a verdict", steps 1 and 2): features on
// the voxelised scan, matches against the model's keypoints, sample consensus with
// pre-rejection, then every hypothesis refined by a short exact ICP and scored by exact
// distances: the exact projection is what makes the score trustworthy (no sampling floor).
#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>
#include <tbb/task_group.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <numeric>
#include <random>

#include "coarse.hpp"
#include "coarse_detail.hpp"
#include "features.hpp"
#include "model_symmetry.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "point_grid.hpp"
#include "verdict.hpp"

namespace nurbsreg::registration::detail {
namespace {

using engine::Vec3;
using Clock = std::chrono::steady_clock;

constexpr std::size_t kMaxScanKeypoints = 20000;
constexpr std::size_t kMinScanKeypoints = 12;
// The first look at every hypothesis (points), and which go on to a short ICP: those whose
// near fraction is at least kGlanceRatio of the best one's, at most kMaxVerified (a part with a
// discrete symmetry needs all its equally good poses verified to report them).
constexpr std::size_t kGlancePoints = 300;
constexpr double kGlanceRatio = 0.6;
constexpr std::size_t kMaxVerified = 6;

struct ScanKeypoints {
  std::vector<Vec3> points;
  std::vector<Vec3> normals;
};

// One point per voxel (the centroid: it averages the noise), kept where PCA finds a surface; a
// seeded subset when a scene yields more than kMaxScanKeypoints.
ScanKeypoints scan_keypoints(std::span<const Vec3> scan, const ModelFeatures& features) {
  const FeatureOptions& fo = features.options();
  const double v = features.voxel();
  const Voxelised vox = voxelise(scan, v);
  const double radius = fo.normal_radius * v;
  const PointGrid grid(vox.centroids, radius);
  const PcaNormals normals = pca_normals(vox.centroids, grid, radius, 5);
  ScanKeypoints out;
  for (std::size_t i = 0; i < vox.centroids.size(); ++i) {
    if (!normals.valid[i]) continue;
    out.points.push_back(vox.centroids[i]);
    out.normals.push_back(normals.normals[i]);
  }
  if (out.points.size() > kMaxScanKeypoints) {
    std::vector<std::size_t> order(out.points.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::mt19937_64 rng(fo.seed);
    for (std::size_t i = 0; i < kMaxScanKeypoints; ++i)
      std::swap(order[i], order[i + static_cast<std::size_t>(rng() % (order.size() - i))]);
    order.resize(kMaxScanKeypoints);
    std::sort(order.begin(), order.end());
    ScanKeypoints kept;
    for (std::size_t i : order) {
      kept.points.push_back(out.points[i]);
      kept.normals.push_back(out.normals[i]);
    }
    out = std::move(kept);
  }
  return out;
}

// The verification subsample: the first m of a seeded permutation of the scan.
std::vector<Vec3> verification_points(std::span<const Vec3> scan, std::size_t m,
                                      std::uint64_t seed) {
  std::vector<Vec3> out;
  if (scan.size() <= m) return {scan.begin(), scan.end()};
  std::vector<std::size_t> order(scan.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::mt19937_64 rng(seed ^ 0x5DEECE66Dull);
  for (std::size_t i = 0; i < m; ++i)
    std::swap(order[i], order[i + static_cast<std::size_t>(rng() % (order.size() - i))]);
  order.resize(m);
  std::sort(order.begin(), order.end());
  out.reserve(m);
  for (std::size_t i : order)
    out.push_back(scan[i]);
  return out;
}

// Exact distances of T * points (those farther than max_distance are +infinity).
void exact_distances(icp::ModelCorrespondenceFinder& finder, const Eigen::Isometry3d& T,
                     std::span<const Vec3> points, double max_distance,
                     std::vector<double>& distances) {
  std::vector<Vec3> moved(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    moved[i] = T * points[i];
  std::vector<icp::Correspondence> c(points.size());
  icp::CorrespondenceQuery q;
  q.points = moved;
  q.max_distance = max_distance;
  finder.reset(points.size());
  finder.find(q, c);
  distances.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    distances[i] = c[i].valid ? c[i].distance : std::numeric_limits<double>::infinity();
}

PoseScore score_of(const Eigen::Isometry3d& T, std::vector<double> d, double tolerance) {
  PoseScore s;
  s.T_model_scan = T;
  if (d.empty()) return s;
  const std::size_t inliers = static_cast<std::size_t>(
      std::count_if(d.begin(), d.end(), [&](double x) { return x <= tolerance; }));
  s.inlier_fraction = static_cast<double>(inliers) / static_cast<double>(d.size());
  const std::size_t half = std::max<std::size_t>(1, d.size() / 2);
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(half - 1), d.end());
  double sum = 0.0;
  for (std::size_t i = 0; i < half; ++i)
    sum += std::isfinite(d[i]) ? d[i] * d[i] : 0.0;
  s.trimmed_rms = std::isfinite(d[half - 1]) ? std::sqrt(sum / static_cast<double>(half))
                                             : std::numeric_limits<double>::infinity();
  return s;
}

bool better(const PoseScore& a, const PoseScore& b) {
  if (a.inlier_fraction != b.inlier_fraction) return a.inlier_fraction > b.inlier_fraction;
  return a.trimmed_rms < b.trimmed_rms;
}

}  // namespace

double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

CoarseOutcome coarse_align(std::span<const Vec3> scan, const ModelFeatures& features,
                           const GlobalOptions& o, double noise,
                           icp::ModelCorrespondenceFinder& finder, Clock::time_point deadline) {
  const auto start = Clock::now();
  CoarseOutcome out;
  // Past the deadline: a failure that says how far the stage got.
  // A cancelled caller (tbb: Ctrl-C in Python cancels its task group) cuts the parallel loops
  // short, leaving partial results: stop at the next check instead of using them.
  const auto past_deadline = [&](const std::string& where) {
    if (tbb::is_current_task_group_canceling()) {
      out.failure = "cancelled in the global alignment " + where;
      return true;
    }
    if (Clock::now() < deadline) return false;
    out.failure = "time limit exceeded in the global alignment " + where;
    out.timed_out = true;
    return true;
  };
  CoarseReport& r = out.report;
  r.method = "fpfh-ransac";
  r.noise = noise;
  const double v = features.voxel();
  r.voxel = v;
  const FeatureOptions& fo = features.options();

  // 1. Features: the scan's keypoints and descriptors, the model's (built once, shared).
  auto lap = [&, last = start](const char* what) mutable {
    const auto now = Clock::now();
    spdlog::debug("coarse: {} in {:.3f} s", what,
                  std::chrono::duration<double>(now - last).count());
    last = now;
  };
  const double cpu0 = process_cpu_seconds();
  features.descriptors();
  features.symmetries();
  r.model_features_cpu_seconds = process_cpu_seconds() - cpu0;
  r.model_features_seconds = std::chrono::duration<double>(Clock::now() - start).count();
  lap("model features (once per model)");
  const ScanKeypoints keys = scan_keypoints(scan, features);
  lap("scan keypoints");
  if (past_deadline("after the scan's keypoints")) return out;
  r.scan_keypoints = keys.points.size();
  const ModelKeypoints& model_keys = features.keypoints();
  r.model_keypoints = model_keys.points.size();
  if (keys.points.size() < kMinScanKeypoints) {
    out.failure = fmt::format(
        "too few points for features: {} surface keypoints at a spacing of {:.3g} (need {}); is "
        "the scan too sparse or too small for this model? Give a starting pose (--init)",
        keys.points.size(), v, kMinScanKeypoints);
    return out;
  }
  const double feature_radius = fo.feature_radius * v;
  const PointGrid grid(keys.points, feature_radius);
  const DescriptorMatrix scan_desc = describe(keys.points, keys.normals, grid, feature_radius);

  // 2. Matches and hypotheses.
  lap("scan descriptors");
  if (past_deadline("after the scan's features")) return out;
  const std::vector<Match> matches = match_descriptors(scan_desc, features.descriptors());
  lap("matches");
  if (past_deadline("after matching features")) return out;
  r.matches = matches.size();
  RansacParams rp;
  rp.seeds = o.ransac_seeds;
  rp.inlier_distance = 2.0 * v;
  rp.min_edge = 4.0 * v;
  rp.keep = o.hypotheses;
  rp.distinct_angle = 10.0 * std::numbers::pi / 180.0;
  rp.distinct_translation = 5.0 * v;
  rp.overlap_cell = v;
  rp.seed = o.seed;
  const std::vector<Hypothesis> hypotheses =
      ransac_hypotheses(keys.points, model_keys.points, matches, rp);
  r.hypotheses = static_cast<int>(hypotheses.size());
  lap("hypotheses");
  if (past_deadline("after the sample consensus")) return out;
  if (hypotheses.empty()) {
    out.failure = fmt::format(
        "the global alignment found no pose: {} feature matches between {} scan and {} model "
        "keypoints gave no consistent triple; does the scan show this model? Give a starting "
        "pose (--init)",
        matches.size(), keys.points.size(), model_keys.points.size());
    return out;
  }

  // 3. Verification: a short exact ICP from each hypothesis, exact distances, score.
  const std::vector<Vec3> sub = verification_points(scan, o.verify_points, o.seed);
  icp::IcpOptions vo;
  vo.max_iterations = o.verify_iterations;
  vo.max_correspondence_distance = 3.0 * v;
  vo.kernel = icp::RobustKernel::tukey;
  vo.auto_coarse = false;
  vo.min_correspondences = 12;
  vo.deadline = deadline;
  icp::IcpSolver solver(vo);
  const double tolerance = std::max(3.0 * noise, 0.02 * v);
  // 3a. A cheap first look: exact distances of a few points at each raw pose, within a voxel and
  // a half (the sample consensus' accuracy). Only the hypotheses near the best of these go on to
  // the short ICP, which costs as much as the rest of the stage per hypothesis.
  std::vector<double> d;
  const std::span<const Vec3> glance(sub.data(), std::min<std::size_t>(sub.size(), kGlancePoints));
  std::vector<std::pair<double, std::size_t>> glanced;
  for (std::size_t i = 0; i < hypotheses.size(); ++i) {
    exact_distances(finder, hypotheses[i].T_model_scan, glance, 3.0 * v, d);
    const double near = static_cast<double>(
        std::count_if(d.begin(), d.end(), [&](double x) { return x <= 1.5 * v; }));
    glanced.emplace_back(near / static_cast<double>(std::max<std::size_t>(1, d.size())), i);
  }
  std::stable_sort(glanced.begin(), glanced.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Hypothesis> promising;
  for (const auto& [near, i] : glanced) {
    if (promising.size() >= kMaxVerified || near < kGlanceRatio * glanced.front().first) break;
    promising.push_back(hypotheses[i]);
  }
  lap("glance");
  std::vector<PoseScore> scored;
  for (const Hypothesis& h : promising) {
    if (past_deadline(
            fmt::format("after verifying {} of {} hypotheses", scored.size(), promising.size()))) {
      return out;
    }
    const icp::IcpResult res = solver.align(finder, sub, h.T_model_scan);
    const bool usable = res.termination != icp::IcpTermination::too_few_correspondences &&
                        res.termination != icp::IcpTermination::numerical_failure &&
                        res.termination != icp::IcpTermination::invalid_input;
    const Eigen::Isometry3d T = usable ? res.T_model_scan : h.T_model_scan;
    exact_distances(finder, T, sub, 3.0 * v, d);
    scored.push_back(score_of(T, d, tolerance));
    spdlog::debug("hypothesis support {} overlap {}: inliers {:.4f}, trimmed rms {:.4g} ({})",
                  h.support, h.overlap, scored.back().inlier_fraction, scored.back().trimmed_rms,
                  icp::to_string(res.termination));
  }
  r.verified = static_cast<int>(scored.size());
  lap("verification");
  std::stable_sort(scored.begin(), scored.end(), better);
  // Poses that converged onto the same one are one pose.
  std::vector<PoseScore> distinct;
  for (const PoseScore& s : scored) {
    const bool seen = std::any_of(distinct.begin(), distinct.end(), [&](const PoseScore& k) {
      return rotation_between(k.T_model_scan, s.T_model_scan) < 2.0 * std::numbers::pi / 180.0 &&
             (k.T_model_scan.translation() - s.T_model_scan.translation()).norm() < 1.0 * v;
    });
    if (!seen) distinct.push_back(s);
  }
  r.winner = distinct.front();
  if (distinct.size() > 1) r.runner_up = distinct[1];
  std::vector<std::string> symmetries;
  for (std::size_t i = 1; i < distinct.size(); ++i) {
    if (distinct[i].inlier_fraction < o.symmetry_ratio * r.winner.inlier_fraction) continue;
    r.alternatives.push_back(distinct[i]);
    symmetries.push_back(describe_symmetry(r.winner.T_model_scan, distinct[i].T_model_scan));
  }
  for (std::size_t i = 0; i < symmetries.size(); ++i)
    r.symmetry += (i ? "; " : "") + symmetries[i];
  // The model's own turns: the sample consensus often finds only one of a symmetric part's
  // equally good poses.
  add_symmetric_alternatives(
      r, features.symmetries(),
      [&](const Eigen::Isometry3d& T) {
        exact_distances(finder, T, sub, 3.0 * v, d);
        return score_of(T, d, tolerance);
      },
      v, o);
  r.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return out;
}

}  // namespace nurbsreg::registration::detail
