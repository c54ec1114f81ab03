// inspect(): the InspectionResult class and the call (inspect_run.hpp does the work).

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <spdlog/fmt/fmt.h>

#include <algorithm>

#include "bindings.hpp"
#include "inspect_run.hpp"

namespace nurbsreg::python {
namespace {

py::dict stats_dict(const inspect::DeviationStats& s) {
  py::dict d;
  d["points"] = s.points;
  d["inside"] = s.inside;
  d["below"] = s.below;
  d["above"] = s.above;
  d["inside_tolerance"] = s.inside_fraction();
  d["mean"] = s.mean;
  d["std"] = s.std;
  d["rms"] = s.rms;
  d["min"] = s.min;
  d["max"] = s.max;
  d["p5"] = s.p5;
  d["p95"] = s.p95;
  return d;
}

template <class T>
py::array_t<T> copy_of(const std::vector<T>& values) {
  return py::array_t<T>(static_cast<py::ssize_t>(values.size()), values.data());
}

}  // namespace

void bind_inspect(py::module_& m) {
  py::class_<InspectionFrame, InspectionFramePtr>(
      m, "InspectionResult", "The deviations of an inspected scan, its statistics and report.")
      .def_property_readonly("alignment", [](const InspectionFrame& f) { return f.alignment; })
      .def_property_readonly("inspected", [](const InspectionFrame& f) { return f.inspected; })
      .def_property_readonly(
          "points",
          [](const InspectionFrame& f) {
            const auto& p = f.deviations.points;
            py::array_t<double> out({static_cast<py::ssize_t>(p.size()), py::ssize_t{3}});
            if (!p.empty()) std::copy_n(p.front().data(), 3 * p.size(), out.mutable_data());
            return out;
          })
      .def_property_readonly(
          "signed_distance",
          [](const InspectionFrame& f) { return copy_of(f.deviations.signed_distance); })
      .def_property_readonly("face",
                             [](const InspectionFrame& f) { return copy_of(f.deviations.face); })
      .def_property_readonly("u", [](const InspectionFrame& f) { return copy_of(f.deviations.u); })
      .def_property_readonly("v", [](const InspectionFrame& f) { return copy_of(f.deviations.v); })
      .def_property_readonly(
          "index", [](const InspectionFrame& f) { return copy_of(f.deviations.source_index); })
      .def_property_readonly(
          "skipped", [](const InspectionFrame& f) { return f.deviations.skipped_nonfinite; })
      .def_property_readonly("unprojected",
                             [](const InspectionFrame& f) { return f.deviations.unprojected; })
      .def_property_readonly("excluded",
                             [](const InspectionFrame& f) { return f.deviations.excluded; })
      .def_property_readonly(
          "summary", [](const InspectionFrame& f) { return stats_dict(f.report.stats.overall); })
      .def_property_readonly("faces",
                             [](const InspectionFrame& f) {
                               py::list faces;
                               for (const inspect::FaceStats& s : f.report.stats.faces) {
                                 py::dict d = stats_dict(s.stats);
                                 d["face"] = s.face;
                                 d["name"] = s.name;
                                 faces.append(d);
                               }
                               return faces;
                             })
      .def_property_readonly("tolerance",
                             [](const InspectionFrame& f) {
                               return py::make_tuple(f.report.stats.tolerance.lower,
                                                     f.report.stats.tolerance.upper);
                             })
      .def_property_readonly("passed", [](const InspectionFrame& f) { return f.report.passed(); })
      .def_property_readonly("warnings", [](const InspectionFrame& f) { return f.warnings; })
      .def("report_json",
           [](const InspectionFrame& f) { return inspect::inspection_json(f.report); })
      .def("faces_csv", [](const InspectionFrame& f) { return inspect::faces_csv(f.report); })
      .def("__len__", [](const InspectionFrame& f) { return f.deviations.size(); })
      .def("__repr__", [](const InspectionFrame& f) {
        const inspect::DeviationStats& s = f.report.stats.overall;
        return fmt::format(
            "<nurbsreg.InspectionResult: {:.2f} % of {} points inside [{:+g}, "
            "{:+g}]: {}>",
            100.0 * s.inside_fraction(), s.points, f.report.stats.tolerance.lower,
            f.report.stats.tolerance.upper, f.report.passed() ? "pass" : "fail");
      });

  m.def(
      "inspect",
      [](PyAligner& aligner, const py::handle& scan,
         const std::optional<py::array_t<std::uint64_t>>& index, std::size_t file_skipped,
         const std::string& scan_name, const py::object& init, const py::object& pose,
         const std::string& global, double tolerance_lower, double tolerance_upper,
         const std::string& colour_scale, std::optional<double> colour_min,
         std::optional<double> colour_max, double min_inside, std::size_t viewer_points,
         bool model_mesh, std::optional<double> exclude_beyond,
         const std::optional<std::string>& out_dir, const std::string& ply, const std::string& html,
         const std::string& png, const std::optional<int>& threads) {
        InspectOptions o{tolerance_lower, tolerance_upper, colour_scale, colour_min,    colour_max,
                         min_inside,      viewer_points,   model_mesh,   exclude_beyond};
        return run_inspect(aligner, scan, index, file_skipped, scan_name, init, pose, global, o,
                           out_dir, ply, html, png, threads);
      },
      py::arg("aligner"), py::arg("scan"), py::arg("index"), py::arg("file_skipped"),
      py::arg("scan_name"), py::arg("init"), py::arg("pose"), py::arg("global_mode"),
      py::arg("tolerance_lower"), py::arg("tolerance_upper"), py::arg("colour_scale"),
      py::arg("colour_min"), py::arg("colour_max"), py::arg("min_inside"), py::arg("viewer_points"),
      py::arg("model_mesh"), py::arg("exclude_beyond"), py::arg("out_dir"), py::arg("ply"),
      py::arg("html"), py::arg("png"), py::arg("threads"));
}

}  // namespace nurbsreg::python
