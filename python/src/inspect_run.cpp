#include "inspect_run.hpp"

#include <pybind11/numpy.h>
#include <spdlog/fmt/fmt.h>

#include <chrono>
#include <cmath>
#include <optional>
#include <regex>

#include "alignment_frame.hpp"
#include "bindings.hpp"
#include "model_handle.hpp"
#include "nurbsreg/inspect/clutter.hpp"
#include "nurbsreg/inspect/inspection.hpp"
#include "nurbsreg/io/alignment_result_report.hpp"
#include "points_arg.hpp"
#include "py_aligner.hpp"
#include "released_call.hpp"

namespace nurbsreg::python {
namespace {

// The library's messages name the CLI's options (`--tolerance-lower`); Python's arguments are
// spelled tolerance_lower.
std::string python_names(const std::string& message) {
  std::string out = message;
  static const std::regex option("--([a-z]+)-([a-z]+)");
  out = std::regex_replace(out, option, "$1_$2");
  static const std::regex single("--([a-z]+)");
  return std::regex_replace(out, single, "$1");
}

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
  if (o.exclude_beyond) {
    if (const auto error =
            inspect::validate_exclusion(*o.exclude_beyond, options.scale.band, "exclude_beyond"))
      throw py::value_error(*error);
  }
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

}  // namespace

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
    report.alignment = inspect::given_pose_alignment(T.matrix(), f->deviations, report.scan_points);
    report.alignment.seconds = since_start();
  }
  report.alignment_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - alignment_start).count();
  if (f->deviations.unprojected > 0) {
    f->warnings.push_back(
        fmt::format("scan: {} points have no closest point on the model and are not inspected",
                    f->deviations.unprojected));
  }
  if (inspect_options.exclude_beyond) {
    inspect::exclude_beyond(f->deviations, *inspect_options.exclude_beyond);
  } else if (const auto hint = inspect::clutter_hint(f->deviations, options.scale.band,
                                                     options.min_inside, "exclude_beyond")) {
    f->warnings.push_back("scan: " + *hint);
  }
  run_released(thread_count(threads), false, [&] {
    if (folder) {
      report = inspect::run_inspection(model->prepared(), f->deviations, std::move(report), options,
                                       *folder);
      folder->commit();
    } else {
      inspect::InspectionOutputs outputs;
      outputs.ply = ply;
      outputs.png = png;
      outputs.html = html;
      report = inspect::run_inspection(model->prepared(), f->deviations, std::move(report), options,
                                       outputs);
    }
  });
  f->inspected = true;
  return f;
}
}  // namespace nurbsreg::python
