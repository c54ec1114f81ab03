// align(): registration::Aligner, the one alignment call behind the CLI's align and batch. One
// Python Aligner keeps one C++ Aligner, so frame after frame reuses its warm state (per-point
// arrays, projection hints) as the C++ API does.

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <spdlog/fmt/fmt.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>

#include "alignment_frame.hpp"
#include "bindings.hpp"
#include "model_handle.hpp"
#include "nurbsreg/io/alignment_report.hpp"
#include "nurbsreg/registration/alignment.hpp"
#include "points_arg.hpp"
#include "py_aligner.hpp"

namespace nurbsreg::python {
namespace {

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

void bind_verdict(py::module_& m) {
  using registration::FitVerdict;
  py::class_<FitVerdict>(m, "FitVerdict",
                         "The verdict on a final pose: good or poor, with the numbers behind it.")
      .def_property_readonly(
          "fit", [](const FitVerdict& f) { return std::string(f.word()); }, "\"good\" or \"poor\".")
      .def_readonly("good", &FitVerdict::good)
      .def_readonly("noise", &FitVerdict::noise,
                    "The noise sigma of the tolerance (model units): the smaller of scan_noise "
                    "and fit_noise.")
      .def_readonly("scan_noise", &FitVerdict::scan_noise,
                    "The scan's own noise estimate (local quadrics; independent of the pose).")
      .def_readonly("fit_noise", &FitVerdict::fit_noise,
                    "The noise of the exact distances at the pose (robust; 0: too few points).")
      .def_readonly("tolerance", &FitVerdict::tolerance,
                    "Inlier tolerance: 3 x noise (with a floor of 1e-5 x the scan's size).")
      .def_readonly("inlier_fraction", &FitVerdict::inlier_fraction,
                    "Fraction of all scan points with exact distance <= tolerance.")
      .def_readonly("rms", &FitVerdict::rms, "RMS of the inliers' exact distances.")
      .def_readonly("rms_over_noise", &FitVerdict::rms_ratio,
                    "rms / noise (about 1 for a good fit; 0 when the noise is 0).")
      .def_readonly("coverage", &FitVerdict::coverage,
                    "Fraction of the model's keypoints near an inlier.")
      .def_readonly("reason", &FitVerdict::reason, "Why poor; empty when good.")
      .def("__repr__", [](const FitVerdict& f) {
        return fmt::format(
            "<nurbsreg.FitVerdict {}: inliers {:.4g}, rms {:.4g} (noise {:.4g}), coverage "
            "{:.4g}>",
            f.word(), f.inlier_fraction, f.rms, f.noise, f.coverage);
      });

  using registration::PoseScore;
  py::class_<PoseScore>(m, "PoseScore", "One verified hypothesis of the global coarse stage.")
      .def_property_readonly(
          "T_model_scan",
          [](const PoseScore& p) { return Eigen::Matrix4d(p.T_model_scan.matrix()); },
          "(4, 4) the pose after the hypothesis' short exact ICP.")
      .def_readonly("inlier_fraction", &PoseScore::inlier_fraction,
                    "Its inlier fraction on the verification subsample.")
      .def_readonly("trimmed_rms", &PoseScore::trimmed_rms,
                    "RMS of the closer half of its exact distances.")
      .def("__repr__", [](const PoseScore& p) {
        return fmt::format("<nurbsreg.PoseScore inliers {:.4g}, trimmed rms {:.4g}>",
                           p.inlier_fraction, p.trimmed_rms);
      });

  using registration::CoarseReport;
  py::class_<CoarseReport>(m, "CoarseReport",
                           "The global coarse stage of an alignment from any pose.")
      .def_readonly("method", &CoarseReport::method)
      .def_readonly("scan_keypoints", &CoarseReport::scan_keypoints)
      .def_readonly("model_keypoints", &CoarseReport::model_keypoints)
      .def_readonly("matches", &CoarseReport::matches)
      .def_readonly("hypotheses", &CoarseReport::hypotheses, "Kept from sample consensus.")
      .def_readonly("verified", &CoarseReport::verified, "Refined by exact ICP and scored.")
      .def_readonly("voxel", &CoarseReport::voxel)
      .def_readonly("noise", &CoarseReport::noise)
      .def_readonly("winner", &CoarseReport::winner)
      .def_readonly("runner_up", &CoarseReport::runner_up,
                    "The best pose clearly different from the winner, or None.")
      .def_readonly("alternatives", &CoarseReport::alternatives,
                    "Distinct poses that fit as well as the winner (a symmetry of the part).")
      .def_readonly("symmetry", &CoarseReport::symmetry,
                    "The symmetry the alternatives show, in words; empty when the pose is unique.")
      .def_readonly("seconds", &CoarseReport::seconds)
      .def("__repr__", [](const CoarseReport& c) {
        return fmt::format("<nurbsreg.CoarseReport {}: {} hypotheses, winner {:.4g}{}>", c.method,
                           c.verified, c.winner.inlier_fraction,
                           c.runner_up
                               ? fmt::format(", runner-up {:.4g}", c.runner_up->inlier_fraction)
                               : std::string());
      });
}

void bind_alignment(py::module_& m) {
  bind_verdict(m);
  py::class_<AlignmentFrame, AlignmentFramePtr>(m, "AlignmentResult")
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
      .def_property_readonly("seconds", [](const AlignmentFrame& f) { return f.seconds; })
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
                               out["within"] = d.within;
                               out["mean"] = d.mean;
                               out["rms"] = d.rms;
                               out["median"] = d.p50;
                               out["p95"] = d.p95;
                               out["p99"] = d.p99;
                               out["max"] = d.max;
                               return out;
                             })
      .def_property_readonly("failure", [](const AlignmentFrame& f) { return f.result.failure; })
      .def_property_readonly(
          "fit",
          [](const AlignmentFrame& f) -> std::optional<registration::FitVerdict> {
            if (!f.result.fit.evaluated) return std::nullopt;
            return f.result.fit;
          })
      .def_property_readonly("coarse", [](const AlignmentFrame& f) { return f.result.coarse; })
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
                       double kernel_scale, const std::vector<std::size_t>& coarse,
                       bool accept_poor, double min_inlier_fraction) {
             return std::make_unique<PyAligner>(
                 std::move(model),
                 make_icp_options(method, max_iterations, max_distance, keep_fraction, kernel,
                                  kernel_scale, coarse),
                 make_registration_options(accept_poor, min_inlier_fraction));
           }),
           py::arg("model"), py::arg("method"), py::arg("max_iterations"), py::arg("max_distance"),
           py::arg("keep_fraction"), py::arg("kernel"), py::arg("kernel_scale"), py::arg("coarse"),
           py::arg("accept_poor"), py::arg("min_inlier_fraction"))
      .def(
          "align",
          [](PyAligner& a, const py::handle& scan, const py::object& init,
             const std::string& global, bool distances, const std::optional<int>& threads) {
            return a.align(scan, init, global, distances, threads);
          },
          py::arg("scan"), py::arg("init"), py::arg("global_mode"), py::arg("distances"),
          py::arg("threads"))
      .def_property_readonly("model", &PyAligner::model);
}

}  // namespace nurbsreg::python
