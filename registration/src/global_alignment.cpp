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
#include <string_view>

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
// The short ICPs' steps (iterations between the duplicate and rejection checks), and the
// iterations before a clearly worse hypothesis may be rejected.
constexpr int kVerifyStep = 4;
constexpr int kRejectAfter = 8;
// The short ICPs' iterations before the rejection check run on the glance points (a fifth of
// the verification subsample), the later ones on the whole subsample, on which every pose is
// scored: most hypotheses verified end as duplicates or rejected by then, and a wrong one cost
// as much as the rest of the stage on the whole subsample.
constexpr int kGlanceIterations = kRejectAfter;
// The short ICPs' first iterations weigh the correspondences with a Tukey scale of one voxel (the
// sample consensus' accuracy), the later ones with the scale estimated from the residuals. A
// hypothesis that fits a part's large plane but not its small features (an assembly's base
// plate, a few voxels off in its own plane) has most residuals at the noise level: the
// estimated scale is then that small, and rejects the very correspondences that would pull the
// small features, and with them the pose, into place.
constexpr int kWideScaleIterations = 6;
// The second round's seed matches at most.
constexpr std::size_t kMaxSeedsRetry = 20000;
// A running short ICP is a duplicate once it is this close to a scored pose (voxels, degrees):
// much closer than same_pose's voxel. A scored pose can be a slow slide on a part's large faces
// (the walls that would stop it farther than the kernel's cut-off) a fraction of a voxel from
// the right pose, and a hypothesis passing within a voxel of it on its way to the right pose is
// no duplicate (NIST CTC-02 with 20% outliers: 18 mm apart at a voxel of 22 mm).
constexpr double kDuplicateVoxels = 0.1;
constexpr double kDuplicateDegrees = 0.25;

// One point per voxel (the centroid: it averages the noise), kept where PCA finds a surface; a
// seeded subset when a scene yields more than kMaxScanKeypoints.
SurfacePoints scan_keypoints(std::span<const Vec3> scan, const ModelFeatures& features) {
  const FeatureOptions& fo = features.options();
  const double v = features.voxel();
  const Voxelised vox = voxelise(scan, v);
  // Clutter spread through the scan's box leaves a point or two in most voxels around the part,
  // and those voxels' centroids outnumber the surface's within a normal's radius: the PCA then
  // finds no surface (NIST CTC-02 with 20% outliers in its box: 720 keypoints of about 2,800).
  // So only the voxels about as full as a typical point's (a sparse scan, a couple of points per
  // voxel, keeps all).
  const std::uint32_t min_count = surface_voxel_count(vox.counts, 1);
  std::vector<Vec3> dense;
  dense.reserve(vox.centroids.size());
  for (std::size_t i = 0; i < vox.centroids.size(); ++i) {
    if (vox.counts[i] >= min_count) dense.push_back(vox.centroids[i]);
  }
  SurfacePoints out = surface_points(dense, fo.normal_radius * v);
  if (out.points.size() > kMaxScanKeypoints) {
    std::vector<std::size_t> order(out.points.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::mt19937_64 rng(fo.seed);
    for (std::size_t i = 0; i < kMaxScanKeypoints; ++i)
      std::swap(order[i], order[i + static_cast<std::size_t>(rng() % (order.size() - i))]);
    order.resize(kMaxScanKeypoints);
    std::sort(order.begin(), order.end());
    SurfacePoints kept;
    for (std::size_t i : order) {
      kept.points.push_back(out.points[i]);
      kept.normals.push_back(out.normals[i]);
    }
    out = std::move(kept);
  }
  return out;
}

// The first m of a seeded permutation of the scan, in scan order (the whole scan when m >= its
// size): the verification subsample, and the points a large scan's keypoints come from.
std::vector<Vec3> seeded_subset(std::span<const Vec3> scan, std::size_t m, std::uint64_t seed) {
  std::vector<Vec3> out;
  if (scan.size() <= m) return {scan.begin(), scan.end()};
  std::vector<std::size_t> order(scan.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::mt19937_64 rng(seed);
  for (std::size_t i = 0; i < m; ++i)
    std::swap(order[i], order[i + static_cast<std::size_t>(rng() % (order.size() - i))]);
  order.resize(m);
  std::sort(order.begin(), order.end());
  out.reserve(m);
  for (std::size_t i : order)
    out.push_back(scan[i]);
  return out;
}

// One hypothesis's short ICP runs in steps (one IcpSolver::align each, for the duplicate and
// rejection checks between them), and every align() starts with the finder's reset(), which
// drops the per-point hints: each step's first pass, and the score's after the last, would
// project the subsample cold although the points moved by a fraction of a voxel since the pass
// before. This finder passes everything through but skips the reset while the same points are
// asked again (warm), so that the steps and the score of one hypothesis continue from the
// previous answers. Hints only speed the exact projection up: every answer is still the exact
// closest point, warm or cold (icp/model_finder.hpp).
class ContinuingFinder final : public icp::CorrespondenceFinder {
 public:
  explicit ContinuingFinder(icp::ModelCorrespondenceFinder& finder) : finder_(finder) {}
  // The next reset() is done: a new hypothesis, or the finder has answered other points since.
  void start_over() { warm_ = false; }
  void reset(std::size_t scan_size) override {
    if (warm_ && scan_size == size_) return;
    finder_.reset(scan_size);
    size_ = scan_size;
    warm_ = true;
  }
  void find(const icp::CorrespondenceQuery& query, std::span<icp::Correspondence> out) override {
    finder_.find(query, out);
  }

 private:
  icp::ModelCorrespondenceFinder& finder_;
  std::size_t size_ = 0;
  bool warm_ = false;
};

// Exact distances of T * points (those farther than max_distance are +infinity).
void exact_distances(icp::CorrespondenceFinder& finder, const Eigen::Isometry3d& T,
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

bool converging_onto(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double voxel) {
  return rotation_between(a, b) < kDuplicateDegrees * std::numbers::pi / 180.0 &&
         (a.translation() - b.translation()).norm() < kDuplicateVoxels * voxel;
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
      out.cancelled = true;
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
  auto lap = [&, last = start, last_cpu = process_cpu_seconds()](const char* what) mutable {
    const auto now = Clock::now();
    const double cpu = process_cpu_seconds();
    spdlog::debug("coarse: {} in {:.3f} s ({:.3f} CPU s)", what,
                  std::chrono::duration<double>(now - last).count(), cpu - last_cpu);
    last = now;
    last_cpu = cpu;
  };
  const double cpu0 = process_cpu_seconds();
  features.descriptors();
  features.symmetries();
  r.model_features_cpu_seconds = process_cpu_seconds() - cpu0;
  r.model_features_seconds = std::chrono::duration<double>(Clock::now() - start).count();
  lap("model features (once per model)");
  // A large scan's keypoints come from a subset of it (GlobalOptions::feature_points); `draw`
  // picks which (a last round draws another).
  const bool subset_keypoints = o.feature_points > 0 && scan.size() > o.feature_points;
  const auto keypoints_of_draw = [&](std::uint64_t draw) {
    return subset_keypoints ? scan_keypoints(seeded_subset(scan, o.feature_points,
                                                           (o.seed + draw) ^ 0x9E3779B97F4A7C15ull),
                                             features)
                            : scan_keypoints(scan, features);
  };
  SurfacePoints keys = keypoints_of_draw(0);
  lap("scan keypoints");
  if (past_deadline("after the scan's keypoints")) return out;
  r.scan_keypoints = keys.points.size();
  // The model's keypoints as the scan's are described (ModelFeatures::described_keypoints), the
  // matches' model side; all of them stand for its surface in the hypotheses' overlap.
  const ModelKeypoints& model_keys = features.described_keypoints();
  const std::span<const Vec3> model_surface = features.keypoints().points;
  r.model_keypoints = model_keys.points.size();
  if (keys.points.size() < kMinScanKeypoints) {
    out.failure = fmt::format(
        "too few points for features: {} surface keypoints at a spacing of {:.3g} (need {}); is "
        "the scan too sparse or too small for this model? Give a starting pose (--init)",
        keys.points.size(), v, kMinScanKeypoints);
    return out;
  }
  const double feature_radius = fo.feature_radius * v;
  const auto matches_of = [&](const SurfacePoints& k) {
    const PointGrid grid(k.points, feature_radius);
    const DescriptorMatrix scan_desc = describe(k.points, k.normals, grid, feature_radius);
    lap("scan descriptors");
    return match_descriptors(scan_desc, features.descriptors());
  };

  // 2. Matches and hypotheses.
  std::vector<Match> matches = matches_of(keys);
  if (past_deadline("after the scan's features")) return out;
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

  // 3. Verification: a short exact ICP from each hypothesis, exact distances, score.
  const std::vector<Vec3> sub = seeded_subset(scan, o.verify_points, o.seed ^ 0x5DEECE66Dull);
  // The first look's points: every k-th of the verification subsample (itself a random
  // subset in scan order, so a stride keeps it random and spread over the scan).
  const std::size_t glance_stride = std::max<std::size_t>(1, sub.size() / kGlancePoints);
  std::vector<Vec3> glance;
  for (std::size_t i = 0; i < sub.size(); i += glance_stride)
    glance.push_back(sub[i]);
  icp::IcpOptions vo;
  vo.max_correspondence_distance = 3.0 * v;
  vo.kernel = icp::RobustKernel::tukey;
  vo.auto_coarse = false;
  vo.min_correspondences = 12;
  vo.deadline = deadline;
  const double tolerance = std::max(3.0 * noise, 0.02 * v);
  const auto near_fraction = [](std::span<const double> d, double limit) {
    const auto n = std::count_if(d.begin(), d.end(), [&](double x) { return x <= limit; });
    return static_cast<double>(n) / static_cast<double>(std::max<std::size_t>(1, d.size()));
  };
  std::vector<double> d;
  ContinuingFinder continuing(finder);
  std::vector<PoseScore> scored;
  // The glance points' fraction within the tolerance at each scored pose (the early rejection
  // compares a running ICP with the best of these).
  double best_quick = 0.0;
  int total_hypotheses = 0;
  // One round: sample consensus, a first look at every hypothesis, the short ICPs of the most
  // promising, each scored. `iterations`: the short ICP's at most.
  const auto search = [&](const RansacParams& params, int iterations) -> bool {
    const std::vector<Hypothesis> hypotheses =
        ransac_hypotheses(keys.points, model_keys.points, matches, params, model_surface);
    total_hypotheses += static_cast<int>(hypotheses.size());
    lap("hypotheses");
    if (past_deadline("after the sample consensus")) return false;
    // 3a. A cheap first look: exact distances of a few points at each raw pose, within a voxel
    // and a half (the sample consensus' accuracy). Only the hypotheses near the best of these go
    // on to the short ICP, which costs as much as the rest of the stage per hypothesis.
    std::vector<std::pair<double, std::size_t>> glanced;
    for (std::size_t i = 0; i < hypotheses.size(); ++i) {
      exact_distances(finder, hypotheses[i].T_model_scan, glance, 3.0 * v, d);
      glanced.emplace_back(near_fraction(d, 1.5 * v), i);
    }
    std::stable_sort(glanced.begin(), glanced.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    std::vector<std::pair<Hypothesis, double>> promising;
    for (const auto& [near, i] : glanced) {
      if (promising.size() >= kMaxVerified || near < kGlanceRatio * glanced.front().first) break;
      promising.emplace_back(hypotheses[i], near);
    }
    lap("glance");
    // 3b. The short ICPs, in steps of kVerifyStep iterations: one that comes onto a pose already
    // scored (converging_onto) converges there (it stops: a duplicate), and one that, after
    // kRejectAfter iterations, puts less than half as many glance points within the tolerance as
    // the best scored pose does is clearly worse (it stops: rejected). The rest run to convergence
    // or to `iterations` (on the whole verification subsample after kGlanceIterations), and are
    // scored on the whole verification subsample.
    for (const auto& [h, near] : promising) {
      if (past_deadline(fmt::format("after verifying {} hypotheses", r.verified))) return false;
      ++r.verified;
      continuing.start_over();
      Eigen::Isometry3d T = h.T_model_scan;
      const char* outcome = "max_iterations";
      for (int done = 0; done < iterations;) {
        // The first step is short: a duplicate is usually on its pose after two iterations.
        vo.max_iterations = std::min(done == 0 ? 2 : kVerifyStep, iterations - done);
        vo.kernel_scale = done < kWideScaleIterations ? v : 0.0;
        const std::vector<Vec3>& points = done < kGlanceIterations ? glance : sub;
        const icp::IcpResult res = icp::IcpSolver(vo).align(continuing, points, T);
        if (res.termination == icp::IcpTermination::too_few_correspondences ||
            res.termination == icp::IcpTermination::numerical_failure ||
            res.termination == icp::IcpTermination::invalid_input) {
          outcome = "failed";
          break;
        }
        if (res.termination == icp::IcpTermination::time_limit) {
          if (!past_deadline("while verifying hypotheses")) {
            out.failure = "time limit exceeded in the global alignment while verifying hypotheses";
            out.timed_out = true;
          }
          return false;
        }
        T = res.T_model_scan;
        done += vo.max_iterations;
        if (res.termination != icp::IcpTermination::max_iterations && vo.kernel_scale > 0.0) {
          // Converged with the voxel-wide scale: that optimum is pulled by the outliers within a
          // voxel of the surface, which a dense clutter around a small part has many of (linkrods
          // with 20% outliers in its box: stuck 0.4 degrees off, 39% inliers, where the next
          // iterations with the residuals' scale reach all 80%). Go on with that scale.
          done = std::max(done, kWideScaleIterations);
          continue;
        }
        if (res.termination != icp::IcpTermination::max_iterations) {
          outcome = "converged";
          break;
        }
        if (std::any_of(scored.begin(), scored.end(), [&](const PoseScore& k) {
              return converging_onto(k.T_model_scan, T, v);
            })) {
          outcome = "duplicate";
          break;
        }
        if (done >= kRejectAfter && best_quick > 0.0) {
          exact_distances(finder, T, glance, 3.0 * v, d);
          continuing.start_over();  // the finder now holds the glance points' answers
          if (near_fraction(d, tolerance) < 0.5 * best_quick) {
            outcome = "rejected";
            break;
          }
        }
      }
      const bool dropped =
          std::string_view(outcome) == "duplicate" || std::string_view(outcome) == "rejected";
      if (!dropped) {
        // Warm from the short ICP's last pass (the same points, within the same distance).
        exact_distances(continuing, T, sub, 3.0 * v, d);
        scored.push_back(score_of(T, d, tolerance));
        std::vector<double> quick;
        for (std::size_t i = 0; i < sub.size(); i += glance_stride)
          quick.push_back(d[i]);
        best_quick = std::max(best_quick, near_fraction(quick, tolerance));
      }
      spdlog::debug("hypothesis support {} overlap {} glance {:.3f}: {}{}", h.support, h.overlap,
                    near, outcome,
                    dropped
                        ? std::string()
                        : fmt::format(", inliers {:.4f}, trimmed rms {:.4g}",
                                      scored.back().inlier_fraction, scored.back().trimmed_rms));
    }
    return true;
  };
  if (!search(rp, o.verify_iterations)) return out;
  const auto best_fraction = [&] {
    double best = 0.0;
    for (const PoseScore& s : scored)
      best = std::max(best, s.inlier_fraction);
    return best;
  };
  // A hard scan (a partial view of a part with large plane faces, many outliers): no verified
  // pose fits. A second round draws from every match (more draws each, more hypotheses kept)
  // and lets the short ICPs run longer; it costs time only where the first round failed.
  if (best_fraction() < o.retry_inlier_fraction && !matches.empty()) {
    spdlog::debug("coarse: best verified inlier fraction {:.3f}: a second, exhaustive round",
                  best_fraction());
    RansacParams wide = rp;
    wide.seeds = static_cast<int>(std::min<std::size_t>(matches.size(), kMaxSeedsRetry));
    wide.draws_per_seed = 2 * rp.draws_per_seed;
    wide.keep = 4 * rp.keep;
    wide.seed = rp.seed + 1;
    if (!search(wide, 2 * o.verify_iterations)) return out;
    // Still none: the sample consensus can miss on one draw (a half view of NIST CTC-02 at 1 M
    // points, one pose in ten: neither round held the pose, best 4.4% inliers; a third round
    // with another seed finds it, as does one on another keypoint subset). One more exhaustive
    // round with fresh draws, on a large scan also on another subset's keypoints; what every
    // round scored is kept. Only where two rounds failed.
    if (best_fraction() < o.retry_inlier_fraction) {
      spdlog::debug("coarse: best verified inlier fraction {:.3f}: a last round, fresh draws{}",
                    best_fraction(), subset_keypoints ? " on another keypoint subset" : "");
      if (subset_keypoints) {
        SurfacePoints other = keypoints_of_draw(1);
        if (other.points.size() >= kMinScanKeypoints) {
          keys = std::move(other);
          matches = matches_of(keys);
          // The report speaks of the keypoints and matches the last round drew from.
          r.scan_keypoints = keys.points.size();
          r.matches = matches.size();
          if (past_deadline("after the scan's features")) return out;
        }
      }
      wide.seed = rp.seed + 2;
      wide.seeds = static_cast<int>(std::min<std::size_t>(matches.size(), kMaxSeedsRetry));
      if (!matches.empty() && !search(wide, 2 * o.verify_iterations)) return out;
    }
  }
  r.hypotheses = total_hypotheses;
  if (scored.empty()) {
    out.failure = fmt::format(
        "the global alignment found no pose: {} feature matches between {} scan and {} model "
        "keypoints gave no consistent triple; does the scan show this model? Give a starting "
        "pose (--init)",
        matches.size(), keys.points.size(), model_keys.points.size());
    return out;
  }
  lap("verification");
  std::stable_sort(scored.begin(), scored.end(), better);
  // Poses that converged onto the same one are one pose.
  std::vector<PoseScore> distinct;
  for (const PoseScore& s : scored) {
    const bool seen = std::any_of(distinct.begin(), distinct.end(), [&](const PoseScore& k) {
      return same_pose(k.T_model_scan, s.T_model_scan, v);
    });
    if (!seen) distinct.push_back(s);
  }
  r.winner = distinct.front();
  if (distinct.size() > 1) r.runner_up = distinct[1];
  std::vector<std::string> symmetries;
  for (std::size_t i = 1; i < distinct.size(); ++i) {
    if (distinct[i].inlier_fraction < o.symmetry_ratio * r.winner.inlier_fraction) continue;
    r.alternatives.push_back(distinct[i]);
    symmetries.push_back(describe_symmetry(r.winner.T_model_scan, distinct[i].T_model_scan,
                                           kSymmetryTextVoxels * v));
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
