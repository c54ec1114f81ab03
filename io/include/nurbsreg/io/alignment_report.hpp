#pragma once
// The alignment report (`align --report R.json`; CONTRACT.md §2 "Alignment report").
//
// A JSON object with at least "pose" (4x4, T_model_scan), "rms", "iterations", "converged",
// "inliers", "points" and "seconds"; this writer adds "method", "termination", "skipped_points",
// "history" (one entry per iteration), "fit" (the verdict: "good" or "poor") with its numbers in
// "fit_details", and "coarse" (the global stage: method, keypoints, matches, hypotheses, the
// winner's and the runner-up's scores, alternatives and symmetry, seconds) when it ran. Numbers are
// written in their shortest exact form; an undefined value (NaN, e.g. the RMS of zero inliers) is
// written as null and read back as NaN. The struct is io's own plain record so io does not depend
// on the ICP result type: the CLI fills it from the ICP result. Thread-safe; allocates (not a hot
// path).

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace nurbsreg::io {

struct IterationRecord {
  int iteration = 0;
  double rms = 0.0;               // RMS point-to-surface distance of the inliers after this step
  std::size_t inliers = 0;        // correspondences kept this iteration
  double rotation_step = 0.0;     // |pose increment| rotation angle, radians
  double translation_step = 0.0;  // |pose increment| translation, model units
  double seconds = 0.0;           // wall time of this iteration
};

// The fit verdict (CONTRACT.md §2 "fit"): good or poor, with the numbers behind it.
struct FitRecord {
  std::string fit;  // "good" or "poor"
  std::string reason;
  double noise = 0.0, tolerance = 0.0, inlier_fraction = 0.0, rms = 0.0, rms_ratio = 0.0,
         coverage = 0.0;
  // registration::FitVerdict's two noise estimates (noise is the smaller); optional in a report.
  double scan_noise = 0.0, fit_noise = 0.0;
};

// One scored pose of the coarse stage.
struct PoseScoreRecord {
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  double inlier_fraction = 0.0;
  double trimmed_rms = 0.0;
};

// The global coarse stage, when it ran.
struct CoarseRecord {
  std::string method;
  std::size_t scan_keypoints = 0, model_keypoints = 0, matches = 0;
  int hypotheses = 0, verified = 0;
  double voxel = 0.0, noise = 0.0, seconds = 0.0;
  // Of `seconds`: building the model's features (once per prepared model; 0 when shared).
  double model_features_seconds = 0.0;
  // The whole alignment from any pose without the model's features: wall and process CPU.
  double alignment_seconds = 0.0, alignment_cpu_seconds = 0.0;
  PoseScoreRecord winner;
  bool has_runner_up = false;
  PoseScoreRecord runner_up;
  std::vector<PoseScoreRecord> alternatives;  // poses that fit as well (a symmetry)
  std::string symmetry;
};

struct AlignmentReport {
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();  // T_model_scan
  double rms = 0.0;
  int iterations = 0;
  bool converged = false;
  std::size_t inliers = 0;
  std::size_t points = 0;          // scan points used (after skipping non-finite ones)
  std::size_t skipped_points = 0;  // scan points skipped (NaN or infinite coordinates)
  double seconds = 0.0;
  std::string method;       // "point-to-plane" or "point-to-point"
  std::string termination;  // why the loop stopped, e.g. "converged: pose increment < 1e-6"
  std::vector<IterationRecord> history;
  bool has_fit = false;
  FitRecord fit;
  bool has_coarse = false;
  CoarseRecord coarse;
};

std::string report_to_json(const AlignmentReport& report);
// Writes report_to_json atomically; throws OutputError.
void write_alignment_report(const std::string& path, const AlignmentReport& report);
// Reads a report (tests, tooling). Requires the contract fields; the others are optional.
// Throws InputError naming the file and field.
AlignmentReport parse_alignment_report(std::string_view text, const std::string& file_label);
AlignmentReport read_alignment_report(const std::string& path);

}  // namespace nurbsreg::io
