// inspect(): the `nurbsreg inspect` command's library calls (cli/inspect_command.cpp) on NumPy
// points: the alignment through the Python Aligner (registration::Aligner, from init or from
// any pose) or a given final pose, inspect::collect_deviations, and then either every output
// into a folder (inspect::run_inspection, as the CLI) or the statistics with only the files
// asked for (the same writers).

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <spdlog/fmt/fmt.h>
#include <tbb/parallel_invoke.h>

#include <chrono>
#include <cmath>
#include <optional>
#include <regex>

#include "alignment_frame.hpp"
#include "bindings.hpp"
#include "model_handle.hpp"
#include "nurbsreg/inspect/deviation_ply.hpp"
#include "nurbsreg/inspect/html_report.hpp"
#include "nurbsreg/inspect/inspection.hpp"
#include "nurbsreg/inspect/picture.hpp"
#include "nurbsreg/inspect/tessellation.hpp"
#include "nurbsreg/inspect/viewer_subset.hpp"
#include "nurbsreg/io/alignment_result_report.hpp"
#include "points_arg.hpp"
#include "py_aligner.hpp"
#include "released_call.hpp"

namespace nurbsreg::python {
namespace {

struct InspectionFrame {
  AlignmentFramePtr alignment;  // null when the final pose was given
  inspect::PointDeviations deviations;
  inspect::InspectionReport report;
  bool inspected = false;  // false: the alignment gave no pose (alignment->failure)
  std::vector<std::string> warnings;
};
using InspectionFramePtr = std::shared_ptr<InspectionFrame>;

// The library's messages name the CLI's options (`--tolerance-lower`); Python's arguments are
// spelled tolerance_lower.
std::string python_names(const std::string& message) {
  std::string out = message;
  static const std::regex option("--([a-z]+)-([a-z]+)");
  out = std::regex_replace(out, option, "$1_$2");
  static const std::regex single("--([a-z]+)");
  return std::regex_replace(out, single, "$1");
}

struct InspectOptions {
  double tolerance_lower = -0.1, tolerance_upper = 0.1;
  std::string colour_scale = "metrology";
  std::optional<double> colour_min, colour_max;
  double min_inside = 0.99;
  std::size_t viewer_points = 300'000;
  bool model_mesh = true;
};

// The CLI's colour_scale() and options, validated before any work.
inspect::InspectionOptions inspection_options(const InspectOptions& o) {
  inspect::Tolerance band{o.tolerance_lower, o.tolerance_upper};
  if (const auto error = band.validate()) throw py::value_error(python_names(*error));
  const auto scheme = inspect::parse_colour_scheme(o.colour_scale);
  if (!scheme) {
    throw py::value_error("colour_scale: expected \"metrology\" or \"blue-red\", got \"" +
                          o.colour_scale + "\"");
  }
  inspect::InspectionOptions options;
  options.scale = inspect::ColourScale::around(band, *scheme);
  if (o.colour_min) options.scale.lower_limit = *o.colour_min;
  if (o.colour_max) options.scale.upper_limit = *o.colour_max;
  if (const auto error = options.scale.validate()) throw py::value_error(python_names(*error));
  if (!(o.min_inside >= 0.0 && o.min_inside <= 1.0)) {
    throw py::value_error(fmt::format("min_inside: must be in [0, 1], got {}", o.min_inside));
  }
  if (o.viewer_points < 1 || o.viewer_points > 5'000'000) {
    throw py::value_error("viewer_points: must be in [1, 5000000]");
  }
  options.min_inside = o.min_inside;
  options.viewer_points = o.viewer_points;
  options.model_mesh = o.model_mesh;
  return options;
}

// File position of aligned point i: `file_index` (a PointCloud's index) of its input row.
std::vector<std::uint64_t> source_rows(std::size_t count, const std::vector<std::uint64_t>& rows,
                                       const std::optional<py::array_t<std::uint64_t>>& file_index,
                                       std::size_t input_rows) {
  std::vector<std::uint64_t> out(count);
  const std::uint64_t* file = nullptr;
  if (file_index) {
    if (static_cast<std::size_t>(file_index->size()) != input_rows) {
      throw std::invalid_argument("index: expected one entry per scan row");
    }
    file = file_index->data();
  }
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint64_t row = rows.empty() ? i : rows[i];
    out[i] = file ? file[row] : row;
  }
  return out;
}

// The statistics and the files asked for, as run_inspection makes them, without a folder.
void inspect_without_folder(const engine::PreparedModel& model, InspectionFrame& f,
                            const inspect::InspectionOptions& options, const std::string& ply,
                            const std::string& html, const std::string& png) {
  const auto start = std::chrono::steady_clock::now();
  inspect::InspectionReport& report = f.report;
  report.scale = options.scale;
  report.min_inside = options.min_inside;
  report.picture_view = inspect::isometric_view().description;
  report.stats = inspect::compute_statistics(f.deviations, model.model(), options.scale.band,
                                             options.scale.lower_limit, options.scale.upper_limit,
                                             options.histogram_bins);
  inspect::ViewerSubset subset;
  inspect::DisplayMesh mesh;
  const bool needs_mesh = options.model_mesh && !(html.empty() && png.empty());
  tbb::parallel_invoke(
      [&] { subset = inspect::viewer_subset(f.deviations.points, options.viewer_points); },
      [&] {
        if (needs_mesh) mesh = inspect::tessellate(model, options.mesh_vertices);
      });
  report.viewer_points = subset.indices.size();
  report.viewer_subset =
      subset.cell == 0.0 ? "every point"
                         : fmt::format("one point per {:.4g} {} grid cell, the first in scan order",
                                       subset.cell, report.units);
  tbb::parallel_invoke(
      [&] {
        if (!ply.empty()) inspect::write_deviation_ply(ply, f.deviations, options.scale);
      },
      [&] {
        if (!png.empty())
          inspect::write_deviation_picture(png, f.deviations, mesh, report, options.picture);
      });
  report.inspection_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!html.empty()) inspect::write_html_report(html, report, f.deviations, subset, mesh);
}

InspectionFramePtr run_inspect(PyAligner& aligner, const py::handle& scan_object,
                               const std::optional<py::array_t<std::uint64_t>>& file_index,
                               std::size_t file_skipped, const std::string& scan_name,
                               const py::object& init, const py::object& pose,
                               const std::string& global, const InspectOptions& inspect_options,
                               const std::optional<std::string>& out_dir, const std::string& ply,
                               const std::string& html, const std::string& png,
                               const std::optional<int>& threads) {
  const auto start = std::chrono::steady_clock::now();
  const auto since_start = [&start] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  const ModelPtr& model = aligner.model();
  const inspect::InspectionOptions options = inspection_options(inspect_options);
  if (!init.is_none() && !pose.is_none()) {
    throw py::value_error(
        "init and pose exclude each other (pose is the final pose: no alignment)");
  }
  // Before the work: an output folder that cannot be written would waste it.
  std::optional<inspect::OutputFolder> folder;
  if (out_dir) {
    try {
      folder.emplace(*out_dir);
    } catch (const std::runtime_error& e) {
      throw py::value_error(std::string("out_dir: ") + e.what());
    }
  }
  auto f = std::make_shared<InspectionFrame>();
  inspect::InspectionReport& report = f->report;
  report.model_file = model->path();
  report.scan_file = scan_name;
  report.units = model->model().units;

  const auto alignment_start = std::chrono::steady_clock::now();
  if (pose.is_none()) {
    // As the CLI: from any pose without init (the global stage), from init as given.
    f->alignment = aligner.align(
        scan_object, init, global, false, threads,
        [&](const registration::Aligner& a, AlignmentFrame& frame) {
          if (frame.result.failure) return;
          const std::vector<std::uint64_t> index =
              source_rows(frame.result.aligned.size(), frame.index, file_index, frame.rows);
          f->deviations = inspect::collect_deviations(frame.result.aligned, a.last_projections(),
                                                      index, file_skipped + frame.skipped);
        });
    const AlignmentFrame& frame = *f->alignment;
    if (frame.result.failure) return f;  // the package raises AlignmentError with it
    report.scan_points = frame.rows - frame.skipped;
    if (frame.result.icp.degeneracy.degenerate())
      report.degeneracy = frame.result.icp.degeneracy.describe();
    // The report counts the file's skipped points too, as the CLI's does.
    report.alignment = io::make_alignment_report(frame.result, frame.method,
                                                 file_skipped + frame.skipped, since_start());
  } else {
    // The final pose is given: the exact projection of every transformed point.
    const Eigen::Isometry3d T = pose_argument(pose, "pose");
    const PointsArg scan(scan_object, "scan");
    run_released(thread_count(threads), scan.size() >= kWatchedPoints, [&] {
      PointsArg::Finite finite = scan.contiguous_finite();
      std::vector<engine::Vec3> aligned(finite.points.size());
      for (std::size_t i = 0; i < aligned.size(); ++i)
        aligned[i] = T * finite.points[i];
      engine::ProjectionResults projections;
      (*model->lease_projector())
          .project(engine::PointView::of(aligned), engine::ProjectionOptions{}, projections);
      const std::vector<std::uint64_t> index =
          source_rows(aligned.size(), finite.rows, file_index, scan.size());
      f->deviations =
          inspect::collect_deviations(aligned, projections, index, file_skipped + finite.skipped);
      report.scan_points = aligned.size();
    });
    if (report.scan_points == 0) throw py::value_error("scan: no finite points to inspect");
    report.pose_given = true;
    report.alignment.pose = T.matrix();
    report.alignment.points = report.scan_points;
    report.alignment.inliers = f->deviations.size();
    report.alignment.skipped_points = f->deviations.skipped_nonfinite;
    report.alignment.converged = true;
    report.alignment.method = "none";
    report.alignment.termination = "pose given (--pose): no alignment";
    double sum_sq = 0.0;
    for (const double d : f->deviations.signed_distance)
      sum_sq += d * d;
    report.alignment.rms =
        f->deviations.size() ? std::sqrt(sum_sq / double(f->deviations.size())) : std::nan("");
    report.alignment.seconds = since_start();
  }
  report.alignment_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - alignment_start).count();
  if (f->deviations.unprojected > 0) {
    f->warnings.push_back(
        fmt::format("scan: {} points have no closest point on the model and are not inspected",
                    f->deviations.unprojected));
  }
  run_released(thread_count(threads), false, [&] {
    if (folder) {
      report = inspect::run_inspection(model->prepared(), f->deviations, std::move(report), options,
                                       *folder);
      folder->commit();
    } else {
      inspect_without_folder(model->prepared(), *f, options, ply, html, png);
    }
  });
  f->inspected = true;
  return f;
}

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
         bool model_mesh, const std::optional<std::string>& out_dir, const std::string& ply,
         const std::string& html, const std::string& png, const std::optional<int>& threads) {
        InspectOptions o{tolerance_lower, tolerance_upper, colour_scale,  colour_min,
                         colour_max,      min_inside,      viewer_points, model_mesh};
        return run_inspect(aligner, scan, index, file_skipped, scan_name, init, pose, global, o,
                           out_dir, ply, html, png, threads);
      },
      py::arg("aligner"), py::arg("scan"), py::arg("index"), py::arg("file_skipped"),
      py::arg("scan_name"), py::arg("init"), py::arg("pose"), py::arg("global_mode"),
      py::arg("tolerance_lower"), py::arg("tolerance_upper"), py::arg("colour_scale"),
      py::arg("colour_min"), py::arg("colour_max"), py::arg("min_inside"), py::arg("viewer_points"),
      py::arg("model_mesh"), py::arg("out_dir"), py::arg("ply"), py::arg("html"), py::arg("png"),
      py::arg("threads"));
}

}  // namespace nurbsreg::python
