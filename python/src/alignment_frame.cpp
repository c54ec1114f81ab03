#include "alignment_frame.hpp"

#include <pybind11/numpy.h>
#include <spdlog/fmt/fmt.h>

#include <limits>
#include <stdexcept>

#include "nurbsreg/io/alignment_result_report.hpp"
#include "nurbsreg/io/pose.hpp"

namespace nurbsreg::python {

icp::IcpOptions make_icp_options(const std::string& method, int max_iterations, double max_distance,
                                 double keep_fraction, const std::string& kernel,
                                 double kernel_scale, const std::vector<std::size_t>& coarse) {
  icp::IcpOptions options;
  const auto m = icp::parse_icp_method(method);
  if (!m)
    throw py::value_error("method: expected \"point-to-plane\" or \"point-to-point\", got \"" +
                          method + "\"");
  options.method = *m;
  const auto k = icp::parse_robust_kernel(kernel);
  if (!k) {
    throw py::value_error(
        "kernel: expected \"none\", \"huber\", \"tukey\" or \"geman-mcclure\", "
        "got \"" +
        kernel + "\"");
  }
  options.kernel = *k;
  options.kernel_scale = kernel_scale;
  options.max_iterations = max_iterations;
  options.max_correspondence_distance = max_distance;
  options.keep_fraction = keep_fraction;
  options.coarse_sizes = coarse;
  if (auto error = options.validate()) throw py::value_error(*error);
  return options;
}

registration::RegistrationOptions make_registration_options(bool accept_poor,
                                                            double min_inlier_fraction) {
  // The CLI's CLI::Range(0.0, 1.0) on --min-inlier-fraction.
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0)) {
    throw py::value_error(
        fmt::format("min_inlier_fraction: must be in [0, 1], got {}", min_inlier_fraction));
  }
  registration::RegistrationOptions options;
  options.verdict.accept_poor = accept_poor;
  options.verdict.min_inlier_fraction = min_inlier_fraction;
  return options;
}

Eigen::Isometry3d pose_argument(const py::handle& pose, const char* name) {
  py::array a;
  try {
    a = py::module_::import("numpy").attr("asarray")(pose, py::arg("dtype") = "float64");
  } catch (py::error_already_set&) {
    throw py::type_error(std::string(name) + ": expected a 4x4 array of numbers");
  }
  if (a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4) {
    throw py::value_error(std::string(name) + ": expected shape (4, 4)");
  }
  const auto values = a.unchecked<double, 2>();
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      M(r, c) = values(r, c);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.matrix() = io::parse_pose(io::pose_to_text(M), name);
  return T;
}

registration::AlignRequest make_request(const py::object& init, const std::string& global) {
  registration::AlignRequest request;
  if (!init.is_none()) request.init = pose_argument(init, "init");
  if (global == "auto") {
    request.global = registration::GlobalMode::automatic;
  } else if (global == "on") {
    // The CLI's `--init auto`: from any pose, so a starting pose would be ignored.
    if (request.init) {
      throw py::value_error(
          "init and global_alignment=True contradict each other (the global stage starts from "
          "any pose)");
    }
    request.global = registration::GlobalMode::on;
  } else if (global == "off") {
    request.global = registration::GlobalMode::off;
  } else {
    throw py::value_error("global_alignment: expected None, True or False");
  }
  return request;
}

void align_rows(registration::Aligner& aligner, const PointsArg& scan,
                const registration::AlignRequest& request, AlignmentFrame& frame) {
  PointsArg::Finite finite = scan.contiguous_finite();
  frame.rows = scan.size();
  frame.skipped = finite.skipped;
  frame.index = std::move(finite.rows);
  if (finite.points.empty()) return;
  try {
    frame.result = aligner.align(finite.points, request);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("scan: ") + e.what());
  }
  if (!frame.has_distances) return;
  // The final exact signed distances (the aligner's last projections) by input row.
  const engine::ProjectionResults& proj = aligner.last_projections();
  frame.signed_distance.assign(frame.rows, std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i = 0; i < proj.size(); ++i)
    frame.signed_distance[frame.index.empty() ? i : frame.index[i]] = proj.signed_distance[i];
}

void add_warnings(AlignmentFrame& frame) {
  const registration::AlignmentResult& f = frame.result;
  const icp::IcpResult& r = f.icp;
  // cli/frame_jobs.cpp: warn_if_unconverged, warn_about_fit, then the sizes and free directions.
  if (r.termination == icp::IcpTermination::max_iterations) {
    frame.warnings.push_back("scan: no convergence within " + std::to_string(frame.max_iterations) +
                             " iterations per stage; the pose may be inaccurate");
  }
  if (f.fit.evaluated && !f.fit.good)
    frame.warnings.push_back("scan: accepted although " + f.fit.reason);
  if (f.coarse && !f.coarse->alternatives.empty()) {
    frame.warnings.push_back(fmt::format(
        "scan: {} other pose(s) fit as well as this one (inliers {:.1f}% vs {:.1f}%): the part "
        "looks symmetric under {}; the result's coarse.alternatives lists them",
        f.coarse->alternatives.size(), 100.0 * f.coarse->alternatives.front().inlier_fraction,
        100.0 * f.coarse->winner.inlier_fraction, f.coarse->symmetry));
  }
  if (const auto note = f.sizes.warning()) frame.warnings.push_back("scan: " + *note);
  if (r.degeneracy.degenerate()) {
    frame.warnings.push_back("the scan does not constrain the pose fully; free directions: " +
                             r.degeneracy.describe());
  }
}

io::AlignmentReport report_of(const AlignmentFrame& frame) {
  return io::make_alignment_report(frame.result, frame.method, frame.skipped, frame.seconds);
}

}  // namespace nurbsreg::python
