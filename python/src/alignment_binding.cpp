// align(): registration::Aligner, the one alignment call behind the CLI's align and batch. One
// Python Aligner keeps one C++ Aligner, so frame after frame reuses its warm state (per-point
// arrays, projection hints) as the C++ API does.

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <cmath>
#include <limits>
#include <mutex>

#include "bindings.hpp"
#include "model_handle.hpp"
#include "nurbsreg/io/alignment_report.hpp"
#include "nurbsreg/io/pose.hpp"
#include "nurbsreg/registration/alignment.hpp"
#include "points_arg.hpp"
#include "released_call.hpp"

namespace nurbsreg::python {
namespace {

// One aligned frame, with what the Python result reports of it.
struct AlignmentFrame {
  registration::AlignmentResult result;
  std::string method;
  std::size_t rows = 0;                 // input rows
  std::size_t skipped = 0;              // rows with a NaN or infinite coordinate
  std::vector<std::uint64_t> index;     // row of each aligned point; empty: the identity
  std::vector<double> signed_distance;  // per input row (NaN: skipped), when asked for
  bool has_distances = false;
  std::vector<std::string> warnings;
};
using FramePtr = std::shared_ptr<AlignmentFrame>;

// The ICP options as the CLI spells them (cli/frame_jobs.cpp icp_options), validated.
icp::IcpOptions make_options(const std::string& method, int max_iterations, double max_distance,
                             double keep_fraction, const std::string& kernel, double kernel_scale,
                             const std::vector<std::size_t>& coarse) {
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

// `init` as the CLI reads --init: the same rigidity check and exact rotation (io::parse_pose on
// the matrix's exact text), so a pose gives the same start as its file.
Eigen::Isometry3d initial_pose(const py::object& init) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (init.is_none()) return T;
  py::array a;
  try {
    a = py::module_::import("numpy").attr("asarray")(init, py::arg("dtype") = "float64");
  } catch (py::error_already_set&) {
    throw py::type_error("init: expected a 4x4 array of numbers");
  }
  if (a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4) {
    throw py::value_error("init: expected shape (4, 4)");
  }
  const auto values = a.unchecked<double, 2>();
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      M(r, c) = values(r, c);
  T.matrix() = io::parse_pose(io::pose_to_text(M), "init");
  return T;
}

class PyAligner {
 public:
  PyAligner(ModelPtr model, icp::IcpOptions options, std::string method)
      : model_(std::move(model)), options_(std::move(options)), method_(std::move(method)) {
    if (model_->model().surfaces.empty()) {
      throw py::value_error(model_->path() + ": align needs a model with surfaces");
    }
    aligner_ = std::make_unique<registration::Aligner>(model_->prepared(), options_);
  }

  FramePtr align(const py::handle& scan_object, const py::object& init_object, bool distances,
                 const std::optional<int>& threads) {
    const PointsArg scan(scan_object, "scan");
    const Eigen::Isometry3d init = initial_pose(init_object);
    // As the CLI: no init means from any pose (the global coarse stage, then ICP).
    const bool from_any_pose = init_object.is_none();
    const int thread_limit = thread_count(threads);
    auto frame = std::make_shared<AlignmentFrame>();
    frame->method = method_;
    frame->rows = scan.size();
    frame->has_distances = distances;
    {
      py::gil_scoped_release release;
      const std::lock_guard lock(mutex_);  // one align() at a time per Aligner
      py::gil_scoped_acquire gil;
      try {
        run_released(thread_limit, scan.size() >= kWatchedPoints, [&] {
          PointsArg::Finite finite = scan.contiguous_finite();
          frame->skipped = finite.skipped;
          frame->index = std::move(finite.rows);
          if (finite.points.empty()) return;
          try {
            frame->result = from_any_pose ? aligner_->align(finite.points)
                                          : aligner_->align(finite.points, init);
          } catch (const std::invalid_argument& e) {
            throw std::invalid_argument(std::string("scan: ") + e.what());
          }
          if (distances) fill_distances(*frame);
        });
      } catch (py::error_already_set&) {
        // Ctrl-C: the cancelled run may have left the warm state half written. Start afresh.
        aligner_ = std::make_unique<registration::Aligner>(model_->prepared(), options_);
        throw;
      }
    }
    if (frame->rows == frame->skipped) {
      throw py::value_error("scan: no finite points to align (" + std::to_string(frame->skipped) +
                            " skipped)");
    }
    const icp::IcpResult& r = frame->result.icp;
    if (r.termination == icp::IcpTermination::max_iterations) {
      frame->warnings.push_back("scan: no convergence within " +
                                std::to_string(options_.max_iterations) +
                                " iterations per stage; the pose may be inaccurate");
    }
    if (const auto note = frame->result.sizes.warning())
      frame->warnings.push_back("scan: " + *note);
    if (r.degeneracy.degenerate()) {
      frame->warnings.push_back("the scan does not constrain the pose fully; free directions: " +
                                r.degeneracy.describe());
    }
    return frame;
  }

  const icp::IcpOptions& options() const { return options_; }
  const ModelPtr& model() const { return model_; }

 private:
  // The final exact signed distances (the aligner's last projections) by input row.
  void fill_distances(AlignmentFrame& frame) const {
    const engine::ProjectionResults& proj = aligner_->last_projections();
    frame.signed_distance.assign(frame.rows, std::numeric_limits<double>::quiet_NaN());
    for (std::size_t i = 0; i < proj.size(); ++i)
      frame.signed_distance[frame.index.empty() ? i : frame.index[i]] = proj.signed_distance[i];
  }

  ModelPtr model_;
  icp::IcpOptions options_;
  std::string method_;
  std::mutex mutex_;
  std::unique_ptr<registration::Aligner> aligner_;
};

// The alignment report as `align --report` writes it (cli/frame_jobs.cpp write_align_outputs),
// without "seconds" of the whole command: ICP's own.
io::AlignmentReport report_of(const AlignmentFrame& f) {
  const icp::IcpResult& result = f.result.icp;
  io::AlignmentReport report;
  report.pose = result.T_model_scan.matrix();
  report.rms = result.rms;
  report.iterations = result.iterations;
  report.converged = result.converged() || result.termination == icp::IcpTermination::degenerate;
  report.inliers = result.inliers;
  report.points = result.points;
  report.skipped_points = f.skipped;
  report.seconds = result.seconds;
  report.method = f.method;
  report.termination = std::string(icp::to_string(result.termination)) + ": " + result.message;
  if (result.degeneracy.degenerate()) {
    report.termination += "; free directions: " + result.degeneracy.describe();
  }
  int k = 0;
  for (const icp::IcpIteration& it : result.log) {
    report.history.push_back(
        {++k, it.rms, it.inliers, it.rotation_step, it.translation_step, it.seconds});
  }
  return report;
}

py::dict degeneracy_of(const icp::DegeneracyReport& d) {
  py::list free;
  for (const icp::FreeDirection& f : d.free_directions) {
    py::dict e;
    e["kind"] = f.kind == icp::FreeDirection::Kind::translation ? "translation"
                : f.kind == icp::FreeDirection::Kind::rotation  ? "rotation"
                                                                : "screw";
    e["direction"] = Eigen::Vector3d(f.direction);
    e["point"] = Eigen::Vector3d(f.point);
    e["pitch"] = f.pitch;
    e["description"] = f.description;
    free.append(e);
  }
  py::dict out;
  out["degenerate"] = d.degenerate();
  out["description"] = d.describe();
  out["free_directions"] = free;
  out["relative_eigenvalues"] = Eigen::Matrix<double, 6, 1>(d.relative_eigenvalues);
  out["eigenvectors"] = Eigen::Matrix<double, 6, 6>(d.eigenvectors);
  out["center"] = Eigen::Vector3d(d.center);
  out["length_scale"] = d.length_scale;
  out["threshold"] = d.threshold;
  return out;
}

py::list history_of(const icp::IcpResult& r) {
  py::list history;
  for (const icp::IcpIteration& it : r.log) {
    py::dict e;
    e["stage"] = it.stage;
    e["points"] = it.points;
    e["inliers"] = it.inliers;
    e["rms"] = it.rms;
    e["kernel_scale"] = it.kernel_scale;
    e["rotation_step"] = it.rotation_step;
    e["translation_step"] = it.translation_step;
    e["step_sigmas"] = it.step_sigmas;
    e["predicted"] = it.predicted;
    e["seconds"] = it.seconds;
    history.append(e);
  }
  return history;
}

// The aligned points by input row (NaN rows stay NaN).
py::array_t<double> aligned_rows(const AlignmentFrame& f) {
  py::array_t<double> out({static_cast<py::ssize_t>(f.rows), py::ssize_t{3}});
  auto a = out.mutable_unchecked<2>();
  for (std::size_t r = 0; r < f.rows; ++r)
    for (int k = 0; k < 3; ++k)
      a(static_cast<py::ssize_t>(r), k) = std::numeric_limits<double>::quiet_NaN();
  const std::vector<engine::Vec3>& aligned = f.result.aligned;
  for (std::size_t i = 0; i < aligned.size(); ++i) {
    const auto r = static_cast<py::ssize_t>(f.index.empty() ? i : f.index[i]);
    for (int k = 0; k < 3; ++k)
      a(r, k) = aligned[i][k];
  }
  return out;
}

}  // namespace

void bind_alignment(py::module_& m) {
  py::class_<AlignmentFrame, FramePtr>(m, "AlignmentResult")
      .def_property_readonly("T_model_scan",
                             [](const AlignmentFrame& f) {
                               return Eigen::Matrix4d(f.result.icp.T_model_scan.matrix());
                             })
      .def_property_readonly("converged",
                             [](const AlignmentFrame& f) {
                               const auto t = f.result.icp.termination;
                               return t == icp::IcpTermination::converged ||
                                      t == icp::IcpTermination::degenerate;
                             })
      .def_property_readonly("termination",
                             [](const AlignmentFrame& f) {
                               return std::string(icp::to_string(f.result.icp.termination));
                             })
      .def_property_readonly("message",
                             [](const AlignmentFrame& f) { return f.result.icp.message; })
      .def_property_readonly("iterations",
                             [](const AlignmentFrame& f) { return f.result.icp.iterations; })
      .def_property_readonly("rms", [](const AlignmentFrame& f) { return f.result.icp.rms; })
      .def_property_readonly("inliers",
                             [](const AlignmentFrame& f) { return f.result.icp.inliers; })
      .def_property_readonly("points", [](const AlignmentFrame& f) { return f.result.icp.points; })
      .def_property_readonly("skipped", [](const AlignmentFrame& f) { return f.skipped; })
      .def_property_readonly("seconds",
                             [](const AlignmentFrame& f) { return f.result.icp.seconds; })
      .def_property_readonly(
          "covariance", [](const AlignmentFrame& f) { return icp::Mat6(f.result.icp.covariance); })
      .def_property_readonly(
          "degeneracy",
          [](const AlignmentFrame& f) { return degeneracy_of(f.result.icp.degeneracy); })
      .def_property_readonly("history",
                             [](const AlignmentFrame& f) { return history_of(f.result.icp); })
      .def_property_readonly("deviation",
                             [](const AlignmentFrame& f) {
                               const registration::DeviationSummary& d = f.result.deviation;
                               py::dict out;
                               out["count"] = d.count;
                               out["mean"] = d.mean;
                               out["rms"] = d.rms;
                               out["median"] = d.p50;
                               out["p95"] = d.p95;
                               out["p99"] = d.p99;
                               out["max"] = d.max;
                               return out;
                             })
      .def_property_readonly("failure", [](const AlignmentFrame& f) { return f.result.failure; })
      .def_property_readonly("scan_size",
                             [](const AlignmentFrame& f) { return f.result.sizes.scan; })
      .def_property_readonly("model_size",
                             [](const AlignmentFrame& f) { return f.result.sizes.model; })
      .def_property_readonly("aligned", &aligned_rows)
      .def_property_readonly("signed_distance",
                             [](const AlignmentFrame& f) -> py::object {
                               if (!f.has_distances) return py::none();
                               return py::array_t<double>(
                                   static_cast<py::ssize_t>(f.signed_distance.size()),
                                   f.signed_distance.data());
                             })
      .def_property_readonly("warnings", [](const AlignmentFrame& f) { return f.warnings; })
      .def("report_json", [](const AlignmentFrame& f) { return io::report_to_json(report_of(f)); })
      .def("__repr__", [](const AlignmentFrame& f) {
        return "<nurbsreg.AlignmentResult: " + f.result.icp.brief_report() + ">";
      });

  py::class_<PyAligner>(m, "Aligner")
      .def(py::init([](ModelPtr model, const std::string& method, int max_iterations,
                       double max_distance, double keep_fraction, const std::string& kernel,
                       double kernel_scale, const std::vector<std::size_t>& coarse) {
             icp::IcpOptions options = make_options(method, max_iterations, max_distance,
                                                    keep_fraction, kernel, kernel_scale, coarse);
             const std::string name(icp::to_string(options.method));
             return std::make_unique<PyAligner>(std::move(model), std::move(options), name);
           }),
           py::arg("model"), py::arg("method"), py::arg("max_iterations"), py::arg("max_distance"),
           py::arg("keep_fraction"), py::arg("kernel"), py::arg("kernel_scale"), py::arg("coarse"))
      .def("align", &PyAligner::align, py::arg("scan"), py::arg("init"), py::arg("distances"),
           py::arg("threads"))
      .def_property_readonly("model", &PyAligner::model);
}

}  // namespace nurbsreg::python
