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
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/io/alignment_report.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/registration/alignment.hpp"

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
  // registration::far_from_model_note: most points far from the model (not in its frame).
  std::optional<std::string> far_note;
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

// The scan's and the model's sizes (registration::ScanSize) for a loaded cloud.
registration::ScanSize scan_size(const io::PointCloud& cloud, const engine::PreparedModel& model);

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

// How align and batch start an alignment (README "Aligning from any pose"): the --init value
// ("": none, so the global coarse stage runs; "auto": the global stage even so; a pose file:
// ICP from it as before), --no-global (ICP from --init or the identity, no global stage) and
// --accept-poor (a poor fit is reported, not failed).
struct GlobalArgs {
  bool no_global = false;
  bool accept_poor = false;
  double min_inlier_fraction = 0.5;
};
void add_global_options(CLI::App& cmd, GlobalArgs& args);
// The request for `init` (the --init value) and the flags; reads the pose file (InputError).
registration::AlignRequest align_request(const std::string& init, const GlobalArgs& args);
registration::RegistrationOptions registration_options(const GlobalArgs& args);
// The model's features an Aligner for `request` needs: through the features cache
// (load_features) when it aligns from any pose, else the cheap parts from the cache when there
// (cached_features). A model the features cannot be built for (no area) is a UsageError naming
// `command`.
std::shared_ptr<const registration::ModelFeatures> features_for(
    const engine::PreparedModel& model, const registration::AlignRequest& request,
    const registration::RegistrationOptions& registration, const std::string& command);
// registration::AlignRequest::progress for a command a person waits on: each line at info.
void log_progress(const std::string& line);

// Where align writes; an empty name means "do not write".
struct AlignOutputs {
  std::string pose;
  std::string aligned;
  std::string report;
};

// An alignment run by the command line: the scan's non-empty points through `aligner` as
// `request` says. Logs each iteration at debug level; throws UsageError when ICP rejects the input
// (IcpTermination::invalid_input). Afterwards `aligner.last_projections()` holds the exact
// projections of the aligned points (for write_align_outputs).
registration::AlignmentResult align_frame(registration::Aligner& aligner,
                                          const io::PointCloud& cloud,
                                          const registration::AlignRequest& request);

// Loud warnings about a frame that stands but deserves a look: a poor fit the user accepted,
// alternatives that fit as well (a symmetric part).
void warn_about_fit(const std::string& scan, const registration::AlignmentResult& frame);

// The warning for a pose that ran out of iterations (IcpTermination::max_iterations), naming the
// scan; nothing otherwise.
void warn_if_unconverged(const std::string& scan, const icp::IcpResult& result,
                         const IcpArgs& args);

// The alignment report (CONTRACT.md §2) of an aligned frame; "seconds" is read from `clock`.
io::AlignmentReport alignment_report(const registration::AlignmentResult& frame,
                                     const io::PointCloud& cloud, const IcpArgs& args,
                                     const Stopwatch& clock);

// Writes the requested outputs of an aligned frame, which `aligner` has just made: its
// last_projections() are read only for an aligned scan (from any pose they are put back in scan
// order on that first read: a run that writes only a pose and a report skips it). The report's
// "seconds" is read from `clock` (the single command: started with the command; batch: with the
// frame).
void write_align_outputs(const registration::AlignmentResult& frame,
                         const registration::Aligner& aligner, const io::PointCloud& cloud,
                         const IcpArgs& args, const AlignOutputs& outputs, const Stopwatch& clock);

}  // namespace nurbsreg::cli
