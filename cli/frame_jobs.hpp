#pragma once
// The per-frame work of `project` and `align`, shared by the single-frame commands and `batch`
// so that a frame processed by `batch` gives byte-for-byte the outputs of a single run.
//
// Each function takes the already-loaded cloud and caller-owned engine objects (Projector,
// correspondence finder, ICP solver) so a batch can prepare the model once and reuse the
// per-thread scratch of those objects over many frames. The functions write their output files
// atomically (io::write_atomically) and return what the command prints; they throw
// io::InputError / io::OutputError / UsageError like the commands do.
//
// Threads: one call at a time per Projector / finder / solver; distinct objects over one shared
// PreparedModel may run concurrently (the PreparedModel is immutable).

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "common.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/io/point_cloud.hpp"

namespace nurbsreg::cli {

// ---- project -------------------------------------------------------------------------------

struct ProjectFrameResult {
  std::size_t points = 0;
  std::size_t skipped = 0;
  double min_distance = 0.0;
  double mean_distance = 0.0;
  double rms_distance = 0.0;
  double max_distance = 0.0;
  double compute_seconds = 0.0;  // projection only (no I/O)
};

// Parses --target; UsageError for anything but surfaces/curves.
engine::ProjectionTarget parse_projection_target(const std::string& target);
// UsageError naming `model_path` when the model has no entity of the target kind.
void check_projection_target(const engine::Model& model, engine::ProjectionTarget target,
                             const std::string& model_path);

// Projects every point of `cloud` and writes the contract's results table to `out` (.csv or
// .pcd; surfaces add signed_distance and normal_x/y/z). `log_progress` logs per block of
// points (long single runs); a batch turns it off.
ProjectFrameResult project_frame(engine::Projector& projector, const io::PointCloud& cloud,
                                 engine::ProjectionTarget target, const std::string& out,
                                 bool log_progress);

// ---- scan against model ----------------------------------------------------------------------

// The sizes (bounding-box diagonals) of a scan and of the model, to tell the user when they are
// far apart: a scan in metres against a model in millimetres is 1/1000 of it, and ICP then
// "aligns" it onto a small patch of the model with a tiny rms; a scan in inches is 1/25.4; a
// scan of a whole scene is much larger than its part.
struct ScanSize {
  double scan = 0.0;
  double model = 0.0;
  std::string units;  // the model's

  // One line when scan / model lies outside [smaller, larger]; nothing otherwise, or when either
  // has no size (a single point).
  std::optional<std::string> note(double smaller, double larger) const;
  // The warning of every command: partial views of large models stay quiet down to 1/200.
  std::optional<std::string> warning() const { return note(1.0 / 200.0, 8.0); }
  // Added to a failed alignment's message, where a mismatch is the likelier cause: 1/10 and 4.
  std::optional<std::string> failure_note() const { return note(0.1, 4.0); }
};
ScanSize scan_size(const io::PointCloud& cloud, const engine::PreparedModel& model);

// ---- align ---------------------------------------------------------------------------------

// The ICP options as the command line spells them (shared by align and batch).
struct IcpArgs {
  std::string method = "point-to-plane";
  int max_iterations = 50;
  double max_distance = std::numeric_limits<double>::infinity();
  double keep_fraction = 1.0;
  std::string kernel = "none";
  double kernel_scale = 0.0;
  std::vector<std::size_t> coarse;
};
void add_icp_options(CLI::App& cmd, IcpArgs& args);
// Validated options; UsageError naming the option.
icp::IcpOptions icp_options(const IcpArgs& args);

// Where align writes; an empty name means "do not write".
struct AlignOutputs {
  std::string pose;
  std::string aligned;
  std::string report;
};

// Deviation of the aligned scan from the model: order statistics of |d| over the inliers.
struct Deviation {
  std::size_t count = 0;
  double mean = 0, rms = 0, p50 = 0, p95 = 0, p99 = 0, max = 0;
};

struct AlignFrameResult {
  icp::IcpResult icp;
  Deviation deviation;
  std::vector<engine::Vec3> aligned;  // T * scan point, for the aligned cloud
};

// Aligns `cloud` (must be non-empty: the caller reports an empty scan) from `init` and computes
// the final deviations; afterwards `finder.last_results()` holds the exact projections of
// `aligned` (for write_align_outputs). Throws UsageError when ICP rejects the input
// (IcpTermination::invalid_input).
AlignFrameResult align_frame(icp::ModelCorrespondenceFinder& finder, icp::IcpSolver& solver,
                             const io::PointCloud& cloud, const Eigen::Isometry3d& init,
                             const IcpArgs& args);

// Why an alignment gave no pose to use, as one line for the user, or nothing. ICP that lost its
// correspondences (fewer inliers than it needs: the scan is too far from the model, beyond
// --max-distance or beside the model's free edges) or whose normal equations broke down returns
// whatever pose it had reached, which aligns nothing. A run that only ran out of iterations is
// not a failure: its pose is reported (converged: false) with warn_if_unconverged's warning.
// The sizes' failure_note, when there is one, ends the line.
std::optional<std::string> alignment_failure(const icp::IcpResult& result, const IcpArgs& args,
                                             const ScanSize& sizes);
// The warning for a pose that ran out of iterations (IcpTermination::max_iterations), naming the
// scan; nothing otherwise.
void warn_if_unconverged(const std::string& scan, const icp::IcpResult& result,
                         const IcpArgs& args);

// Writes the requested outputs of an aligned frame; `projections` are the final ones
// (finder.last_results() right after align_frame). The report's "seconds" is read from `clock`
// (the single command: started with the command; batch: with the frame).
void write_align_outputs(const AlignFrameResult& frame,
                         const engine::ProjectionResults& projections, const io::PointCloud& cloud,
                         const IcpArgs& args, const AlignOutputs& outputs, const Stopwatch& clock);

}  // namespace nurbsreg::cli
