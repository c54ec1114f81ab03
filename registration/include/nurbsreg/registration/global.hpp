#pragma once
// Options and reports of the alignment from any pose (DESIGN.md "From any pose to a verdict"):
// the global coarse stage (features, sample consensus, hypotheses verified by exact ICP and
// exact distances) and the fit verdict every alignment ends with.

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "nurbsreg/registration/model_features.hpp"

namespace nurbsreg::registration {

// When Aligner::align runs the global coarse stage: automatic = when no initial pose is given;
// on = always (an initial pose is then ignored: `--init auto`); off = never (ICP from the
// initial pose, or from the identity: `--no-global`).
enum class GlobalMode { automatic, on, off };

struct GlobalOptions {
  // For the Aligner's own ModelFeatures (when none is shared with it).
  FeatureOptions features;
  // Seed matches of the guided sample consensus (coarse_detail.hpp in src: RansacParams).
  int ransac_seeds = 1500;
  // Hypotheses kept from sample consensus (ranked by how much of the scan they put onto the
  // model); each gets a first look at a few exact distances, and the best few of those are
  // refined by a short exact ICP and scored.
  int hypotheses = 16;
  // The scan's keypoints (one per voxel) come from at most this many of its points (a seeded
  // random subset of a larger scan): a voxel's centroid averages its points, and on a denser
  // scan uniform outliers fill every voxel of the scan's box, so that the keypoints' PCA
  // neighbourhoods see no surface (a 1 M-point scan of NIST CTC-02 with 20% outliers kept 260
  // keypoints, and the stage found no pose). With the cap a large scan's keypoints are those of
  // a scan of this size, the density the stage is tuned and measured at, and cost as little.
  // 0: no cap.
  std::size_t feature_points = 50000;
  // Scan points (a seeded subsample) for refining and scoring a hypothesis, and its iterations.
  std::size_t verify_points = 1500;
  int verify_iterations = 20;
  // A best verified pose with fewer of the subsample's points within the tolerance than this
  // (the verdict's min_inlier_fraction: it would be judged poor) starts a second round from
  // every feature match, with more hypotheses and longer short ICPs.
  double retry_inlier_fraction = 0.5;
  // A distinct refined pose whose inlier fraction is at least this fraction of the winner's
  // fits as well: reported as an alternative (a symmetry of the part) instead of dropped.
  double symmetry_ratio = 0.97;
  // The fine ICP after the coarse stage (only when the user left the kernel at none): Tukey
  // with the inliers' scale; and, when the maximum distance is unbounded, this many voxels.
  bool robust_fine = true;
  double fine_max_distance_voxels = 3.0;
  // The fine ICP after the coarse stage stops on all points when its step (or, with
  // fine_predict_final, its next step predicted from the contraction rate) is at most this many
  // standard deviations of its own pose estimate (icp::IcpOptions::statistical_tolerance, whose
  // default 0.1 costs one or two more passes over every point for a pose change far below its
  // own uncertainty). Without a user's --coarse its stages are fine_stage_sizes (alignment.hpp:
  // a tenth and two fifths of the scan, capped for large scans), then all points. One standard
  // deviation, the step itself (not predicted) and not applied: the returned pose is then the
  // one its last pass evaluated, whose distances the verdict reads (no further pass over every
  // point), within the noise's own uncertainty of the next step's.
  double fine_statistical_tolerance = 1.0;
  bool fine_predict_final = false;
  std::uint64_t seed = 1;
};

struct VerdictOptions {
  // The tolerance of an inlier: this many times the scan's estimated noise (with a floor of
  // 1e-5 of the scan's size, for noise-free scans).
  double tolerance_sigmas = 3.0;
  // Poor below these: the fraction of scan points within the tolerance, the fraction of the
  // model's keypoints with an inlier near them (partial views go down to 25% of the surface).
  double min_inlier_fraction = 0.5;
  double min_coverage = 0.05;
  // A poor fit is a failure (AlignmentResult::failure) unless accepted.
  bool accept_poor = false;
};

struct FitVerdict {
  bool evaluated = false;  // false when there was no pose to judge (an ICP failure)
  bool good = false;
  // The noise sigma the tolerance is made of (model units): the scan's own estimate, or the
  // residuals' at the pose when those are smaller (fit_noise below).
  double noise = 0.0;
  // The scan's own estimate, from local quadrics, independent of the model and the pose. Clutter
  // near the surface and strong curvature inflate it.
  double scan_noise = 0.0;
  // From the exact distances at the final pose: 1.4826 x their median within the scan noise's
  // tolerance, corrected for that truncation (0: too few points within it). Used only to tighten
  // (noise = min(scan_noise, fit_noise)): a wrong pose has larger residuals, so it cannot widen
  // its own tolerance.
  double fit_noise = 0.0;
  double tolerance = 0.0;        // inlier tolerance
  double inlier_fraction = 0.0;  // of all scan points, exact distance <= tolerance
  double rms = 0.0;              // of the inliers' exact distances
  double rms_ratio = 0.0;        // rms / noise (about 1 for a good fit; 0 when noise is 0)
  double coverage = 0.0;         // fraction of the model's keypoints near an inlier
  std::string reason;            // why poor; empty when good
  std::string_view word() const { return good ? "good" : "poor"; }
};

// One verified hypothesis: the pose after its short exact ICP, and its exact score on the
// verification subsample.
struct PoseScore {
  Eigen::Isometry3d T_model_scan = Eigen::Isometry3d::Identity();
  double inlier_fraction = 0.0;
  double trimmed_rms = 0.0;  // rms of the closer half of the exact distances
};

struct CoarseReport {
  std::string method;  // "fpfh-ransac" (sign-invariant FPFH, sample consensus, exact verification)
  // The keypoints described and matched on either side (where PCA finds a surface).
  std::size_t scan_keypoints = 0, model_keypoints = 0, matches = 0;
  int hypotheses = 0;  // kept from sample consensus
  int verified = 0;    // refined by exact ICP and scored
  double voxel = 0.0;
  double noise = 0.0;
  PoseScore winner;
  std::optional<PoseScore> runner_up;  // the best pose clearly different from the winner
  // Distinct poses that fit as well as the winner (symmetry_ratio), the winner excluded, and
  // the symmetry they show ("rotation by 180.0 deg about (0, 0, 1) through (0, 0, 0)", one per
  // alternative, joined by "; "), after the continuous symmetries the final pose leaves free
  // ("continuous rotation about (0.000, 0.000, 1.000) through (0, 0, 20)": a surface of
  // revolution; a plane patch also slides); empty when the pose is unique.
  std::vector<PoseScore> alternatives;
  std::string symmetry;
  double seconds = 0.0;
  // Building the model's features (its surface area, keypoints and descriptors), which a
  // prepared model does once (0 when they were built before: `batch`, the service, a reused
  // Aligner); its keypoints and descriptors are part of `seconds`.
  double model_features_seconds = 0.0, model_features_cpu_seconds = 0.0;
  // The whole alignment from any pose (this stage, the fine ICP, the verdict) without the
  // model's features: wall seconds, and the process's CPU seconds over it (all its threads:
  // meaningful when one alignment runs at a time, as in `align`).
  double alignment_seconds = 0.0;
  double alignment_cpu_seconds = 0.0;
};

}  // namespace nurbsreg::registration
