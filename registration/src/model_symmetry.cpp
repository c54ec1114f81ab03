#include "model_symmetry.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include "coarse_detail.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "verdict.hpp"

namespace nurbsreg::registration::detail {
namespace {

using Eigen::Isometry3d;
using engine::Vec3;

constexpr double kPi = std::numbers::pi;
// Keypoints for the cheap first look at a candidate, and for its refinement and final check.
// Exact points fix an exact turn: a few hundred suffice to refine one.
constexpr std::size_t kGlancePoints = 128;
constexpr std::size_t kFitPoints = 400;
constexpr std::size_t kCheckPoints = 1500;
// A candidate goes on to the refinement when kGlanceFraction of the glance points lies within
// half a voxel, or within what its axis's slack allows: an axis off by an angle a moves a point
// at distance r from it by up to about 2 r a (principal axes of nearly equal spreads are
// ill-defined; the half-turn axes in a plane are sampled every 180 / kPlaneSteps degrees). A
// refined one is a symmetry when kSymmetryFraction of the check points lies within 1% of a
// voxel.
constexpr double kGlanceVoxels = 0.5;
constexpr double kGlanceFraction = 0.6;
constexpr double kIllDefinedAxisSlack = 2.5 * kPi / 180.0;
constexpr double kPrincipalAxisSlack = 0.25 * kPi / 180.0;
constexpr double kSymmetryFraction = 0.99;
constexpr double kSymmetryVoxels = 0.01;
// Two spreads (covariance eigenvalues) within this relative difference make their principal
// axes ill-defined: their plane is searched for half-turn axes every 180 / kPlaneSteps degrees.
constexpr double kEqualSpreads = 0.1;
constexpr int kPlaneSteps = 48;
// A bound on the group (the rotations of a cube are 24; more is a surface of revolution that
// the continuity probes missed).
constexpr std::size_t kMaxSymmetries = 48;
constexpr int kMaxRefinements = 12;

// Every `stride`-th keypoint: a deterministic spread over the model (the keypoints come one
// per voxel in voxel order).
std::vector<Vec3> spread(std::span<const Vec3> points, std::size_t count) {
  std::vector<Vec3> out;
  const std::size_t stride =
      std::max<std::size_t>(1, points.size() / std::max<std::size_t>(1, count));
  for (std::size_t i = 0; i < points.size() && out.size() < count; i += stride)
    out.push_back(points[i]);
  return out;
}

// The fraction of S * points within `tolerance` of the model (exact distances).
double fraction_within(icp::ModelCorrespondenceFinder& finder, const Isometry3d& S,
                       std::span<const Vec3> points, double tolerance, std::vector<Vec3>& moved,
                       std::vector<icp::Correspondence>& found) {
  moved.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    moved[i] = S * points[i];
  found.assign(points.size(), {});
  icp::CorrespondenceQuery q;
  q.points = moved;
  q.max_distance = tolerance;
  finder.reset(points.size());
  finder.find(q, found);
  const auto near = std::count_if(found.begin(), found.end(), [&](const icp::Correspondence& c) {
    return c.valid && c.distance <= tolerance;
  });
  return static_cast<double>(near) / static_cast<double>(std::max<std::size_t>(1, points.size()));
}

Isometry3d turn_about(const Vec3& axis, const Vec3& through, double angle) {
  Isometry3d S = Isometry3d::Identity();
  S.linear() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  S.translation() = through - S.linear() * through;
  return S;
}

// A turn to try: its axis through the keypoints' centroid, and how far off that axis may be
// (radians).
struct Candidate {
  Vec3 axis;
  double angle;
  double axis_slack;
};

// The rms distance of `points` from the line through `c` along the unit vector `a`.
double rms_from_axis(std::span<const Vec3> points, const Vec3& c, const Vec3& a) {
  double sum = 0.0;
  for (const Vec3& p : points)
    sum += ((p - c) - (p - c).dot(a) * a).squaredNorm();
  return std::sqrt(sum / static_cast<double>(std::max<std::size_t>(1, points.size())));
}

}  // namespace

std::vector<Isometry3d> find_model_symmetries(const engine::PreparedModel& model,
                                              const ModelKeypoints& keypoints, double voxel) {
  const std::span<const Vec3> all = keypoints.points;
  if (all.size() < 16 || !(voxel > 0.0)) return {};
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : all)
    centroid += p;
  centroid /= static_cast<double>(all.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const Vec3& p : all)
    covariance += (p - centroid) * (p - centroid).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(covariance);
  const Eigen::Vector3d spreads = eig.eigenvalues();
  const Eigen::Matrix3d axes = eig.eigenvectors();

  // The turns about each principal axis, and the probes that tell a continuous symmetry (turns
  // that are no k-fold symmetry's for the k above).
  std::vector<double> turns;
  for (int k : {2, 3, 4, 5, 6, 8})
    for (int j = 1; j < k; ++j)
      turns.push_back(2.0 * kPi * j / k);
  std::sort(turns.begin(), turns.end());
  turns.erase(std::unique(turns.begin(), turns.end(),
                          [](double a, double b) { return std::abs(a - b) < 1e-9; }),
              turns.end());
  const double continuity_probes[] = {17.0 * kPi / 180.0, 137.5 * kPi / 180.0};

  const std::vector<Vec3> glance = spread(all, kGlancePoints);
  const std::vector<Vec3> fit = spread(all, kFitPoints);
  const std::vector<Vec3> check = spread(all, kCheckPoints);
  icp::ModelCorrespondenceFinder finder(model);
  std::vector<Vec3> moved;
  std::vector<icp::Correspondence> found;
  icp::IcpOptions refine;
  refine.max_iterations = 30;
  refine.max_correspondence_distance = 2.0 * voxel;
  refine.kernel = icp::RobustKernel::tukey;
  refine.auto_coarse = false;
  refine.min_correspondences = 12;
  icp::IcpSolver solver(refine);
  // How much of the model a candidate's turn maps near the model, within its axis's slack.
  auto glance_fraction = [&](const Candidate& c) {
    const double slack = 2.0 * c.axis_slack * rms_from_axis(glance, centroid, c.axis);
    return fraction_within(finder, turn_about(c.axis, centroid, c.angle), glance,
                           std::max(kGlanceVoxels * voxel, slack), moved, found);
  };
  // The exact turn near a candidate's that maps the model onto itself, if there is one.
  auto refined = [&](const Candidate& c) -> std::optional<Isometry3d> {
    const icp::IcpResult r = solver.align(finder, fit, turn_about(c.axis, centroid, c.angle));
    if (r.termination == icp::IcpTermination::invalid_input ||
        r.termination == icp::IcpTermination::too_few_correspondences ||
        r.termination == icp::IcpTermination::numerical_failure) {
      return std::nullopt;
    }
    if (fraction_within(finder, r.T_model_scan, check, kSymmetryVoxels * voxel, moved, found) <
        kSymmetryFraction) {
      return std::nullopt;
    }
    return r.T_model_scan;
  };
  auto symmetry_near = [&](const Candidate& c) -> std::optional<Isometry3d> {
    if (glance_fraction(c) < kGlanceFraction) return std::nullopt;
    return refined(c);
  };
  auto angle_of = [](const Isometry3d& S) { return Eigen::AngleAxisd(S.linear()).angle(); };

  auto equal_spreads = [&](int a, int b) {
    return std::abs(spreads[a] - spreads[b]) <= kEqualSpreads * std::max(spreads[a], spreads[b]);
  };
  std::vector<Candidate> candidates;
  for (int a = 0; a < 3; ++a) {
    const Vec3 axis = axes.col(a);
    const double slack = equal_spreads(a, (a + 1) % 3) || equal_spreads(a, (a + 2) % 3)
                             ? kIllDefinedAxisSlack
                             : kPrincipalAxisSlack;
    // Turns by angles no k-fold symmetry has that still fit: a surface of revolution about
    // this axis (the fine ICP's degeneracy report names it), not a discrete symmetry.
    const bool continuous =
        std::all_of(std::begin(continuity_probes), std::end(continuity_probes), [&](double t) {
          const auto S = symmetry_near({axis, t, slack});
          return S && std::abs(angle_of(*S) - t) < 3.0 * kPi / 180.0;
        });
    if (continuous) continue;
    for (double angle : turns)
      candidates.push_back({axis, angle, slack});
  }
  // Two equal spreads: a half-turn axis (a square plate's diagonals) may lie anywhere in their
  // plane.
  for (int a = 0; a < 3; ++a) {
    const int b = (a + 1) % 3;
    if (!equal_spreads(a, b)) continue;
    for (int step = 1; step < kPlaneSteps; ++step) {
      const double phi = kPi * step / kPlaneSteps;
      candidates.push_back(
          {std::cos(phi) * axes.col(a) + std::sin(phi) * axes.col(b), kPi, kIllDefinedAxisSlack});
    }
  }

  std::vector<Isometry3d> out;
  auto seen = [&](const Isometry3d& S) {
    return std::any_of(out.begin(), out.end(), [&](const Isometry3d& k) {
      return rotation_between(k, S) < 1.0 * kPi / 180.0 &&
             (k.translation() - S.translation()).norm() < 0.1 * voxel;
    });
  };
  // The refinements are what costs: the candidates that look best first, at most
  // kMaxRefinements of them, none near a turn already found (the group products below add
  // the rest of a group from its generators).
  std::vector<std::pair<double, std::size_t>> ranked;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const double f = glance_fraction(candidates[i]);
    if (f >= kGlanceFraction) ranked.emplace_back(f, i);
  }
  std::stable_sort(ranked.begin(), ranked.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  int refinements = 0;
  for (const auto& [f, i] : ranked) {
    if (refinements >= kMaxRefinements) break;
    const Candidate& c = candidates[i];
    const Isometry3d guess = turn_about(c.axis, centroid, c.angle);
    const bool covered = std::any_of(out.begin(), out.end(), [&](const Isometry3d& k) {
      return rotation_between(k, guess) < 2.0 * c.axis_slack + 1.0 * kPi / 180.0;
    });
    if (covered) continue;
    ++refinements;
    const std::optional<Isometry3d> S = refined(c);
    // None, refined back to the identity, or a turn already found from another candidate.
    if (!S || angle_of(*S) < 2.0 * kPi / 180.0) continue;
    if (!seen(*S)) out.push_back(*S);
  }
  // The symmetries form a group: products of those found are symmetries too (exact ones, so
  // only checked), which completes a k-fold axis whose turns the candidates missed.
  for (std::size_t i = 0; i < out.size() && out.size() < kMaxSymmetries; ++i) {
    for (std::size_t j = 0; j <= i && out.size() < kMaxSymmetries; ++j) {
      for (const Isometry3d& S : {out[i] * out[j], out[j] * out[i]}) {
        if (angle_of(S) < 2.0 * kPi / 180.0 || seen(S)) continue;
        if (fraction_within(finder, S, check, kSymmetryVoxels * voxel, moved, found) >=
            kSymmetryFraction) {
          out.push_back(S);
        }
      }
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const Isometry3d& a, const Isometry3d& b) {
    return Eigen::AngleAxisd(a.linear()).angle() < Eigen::AngleAxisd(b.linear()).angle();
  });
  return out;
}

void add_symmetric_alternatives(CoarseReport& report, std::span<const Isometry3d> symmetries,
                                const std::function<PoseScore(const Isometry3d&)>& score,
                                double voxel, const GlobalOptions& options) {
  const Isometry3d winner = report.winner.T_model_scan;
  auto known = [&](const Isometry3d& T) {
    return same_pose(winner, T, voxel) ||
           std::any_of(report.alternatives.begin(), report.alternatives.end(),
                       [&](const PoseScore& a) { return same_pose(a.T_model_scan, T, voxel); });
  };
  for (const Isometry3d& S : symmetries) {
    const Isometry3d T = S * winner;
    if (known(T)) continue;
    const PoseScore s = score(T);
    if (s.inlier_fraction < options.symmetry_ratio * report.winner.inlier_fraction) continue;
    report.alternatives.push_back(s);
    const std::string turn = describe_symmetry(winner, T, kSymmetryTextVoxels * voxel);
    report.symmetry += (report.symmetry.empty() ? "" : "; ") + turn;
  }
}

}  // namespace nurbsreg::registration::detail
