#pragma once
// One aligned frame as the Python results hold it, and the pieces align() and inspect() share
// with the CLI: the ICP options, the start (`init`, the global stage) and the verdict options
// spelled as the CLI spells them (cli/frame_jobs.cpp), the run of registration::Aligner on the
// finite rows, the CLI's warnings and its report (io::make_alignment_report).

#include <pybind11/pybind11.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/io/alignment_report.hpp"
#include "nurbsreg/registration/alignment.hpp"
#include "points_arg.hpp"

namespace nurbsreg::python {

namespace py = pybind11;

struct AlignmentFrame {
  registration::AlignmentResult result;
  icp::IcpMethod method = icp::IcpMethod::point_to_plane;  // the user's, as the report names it
  int max_iterations = 0;
  std::size_t rows = 0;                 // input rows
  std::size_t skipped = 0;              // rows with a NaN or infinite coordinate
  std::vector<std::uint64_t> index;     // row of each aligned point; empty: the identity
  std::vector<double> signed_distance;  // per input row (NaN: skipped), when asked for
  bool has_distances = false;
  std::vector<std::string> warnings;
  double seconds = 0.0;  // wall time of the call (the report's "seconds")
};
using AlignmentFramePtr = std::shared_ptr<AlignmentFrame>;

// The ICP options as the CLI spells them (cli/frame_jobs.cpp icp_options), validated:
// ValueError naming the option.
icp::IcpOptions make_icp_options(const std::string& method, int max_iterations, double max_distance,
                                 double keep_fraction, const std::string& kernel,
                                 double kernel_scale, const std::vector<std::size_t>& coarse);

// `--accept-poor` and `--min-inlier-fraction`; ValueError outside [0, 1].
registration::RegistrationOptions make_registration_options(bool accept_poor,
                                                            double min_inlier_fraction);

// A 4x4 pose as the CLI reads a pose file (io::parse_pose on the matrix's exact text: the same
// rigidity check and exact rotation); `name` names the argument in the errors.
Eigen::Isometry3d pose_argument(const py::handle& pose, const char* name);

// The start as the CLI's align_request: `init` None or a 4x4; `global` "auto" (the global stage
// when there is no init), "on" (--init auto) or "off" (--no-global).
registration::AlignRequest make_request(const py::object& init, const std::string& global);

// Aligns the finite rows of `scan` into `frame` (rows, skipped, index, result; the signed
// distances when frame.has_distances). Callable without the GIL; std::invalid_argument from the
// aligner comes back prefixed "scan: ".
void align_rows(registration::Aligner& aligner, const PointsArg& scan,
                const registration::AlignRequest& request, AlignmentFrame& frame);

// The CLI's warnings about a frame whose pose stands (no convergence, a poor fit accepted, poses
// that fit as well, scan and model sizes, free directions), into frame.warnings.
void add_warnings(AlignmentFrame& frame);

// The report `align --report` writes (io::make_alignment_report), "seconds" the call's.
io::AlignmentReport report_of(const AlignmentFrame& frame);

}  // namespace nurbsreg::python
