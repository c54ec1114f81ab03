#pragma once
// inspect() without Python's types: the `nurbsreg inspect` command's library calls
// (cli/inspect_command.cpp) on NumPy points. The alignment runs through the Python Aligner
// (registration::Aligner, from init or from any pose) unless the final pose is given; then
// inspect::collect_deviations, and either every output into a folder (inspect::run_inspection,
// as the CLI) or the statistics with only the files asked for (the same writers).

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "alignment_frame.hpp"
#include "nurbsreg/inspect/deviations.hpp"
#include "nurbsreg/inspect/inspection_report.hpp"
#include "py_aligner.hpp"

namespace nurbsreg::python {

struct InspectionFrame {
  AlignmentFramePtr alignment;  // null when the final pose was given
  inspect::PointDeviations deviations;
  inspect::InspectionReport report;
  bool inspected = false;  // false: the alignment gave no pose (alignment->failure)
  std::vector<std::string> warnings;
};
using InspectionFramePtr = std::shared_ptr<InspectionFrame>;

// The inspection's options as Python spells them (the CLI's, with underscores).
struct InspectOptions {
  double tolerance_lower = -0.1, tolerance_upper = 0.1;
  std::string colour_scale = "metrology";
  std::optional<double> colour_min, colour_max;
  double min_inside = 0.99;
  std::size_t viewer_points = 300'000;
  bool model_mesh = true;
  std::optional<double> exclude_beyond;  // as `inspect --exclude-beyond`
};

// `scan`: (N, 3) points; `file_index` (a PointCloud's index: file position of each row) and
// `file_skipped` (the file's NaN rows) when they come from a file named `scan_name`; `init` /
// `pose` None or 4x4; `global` as make_request; `out_dir`: every output into that folder, else
// `ply`, `html`, `png` when not empty. The alignment's failure comes back in
// result->alignment->result.failure (result->inspected false, nothing written).
InspectionFramePtr run_inspect(PyAligner& aligner, const py::handle& scan,
                               const std::optional<py::array_t<std::uint64_t>>& file_index,
                               std::size_t file_skipped, const std::string& scan_name,
                               const py::object& init, const py::object& pose,
                               const std::string& global, const InspectOptions& options,
                               const std::optional<std::string>& out_dir, const std::string& ply,
                               const std::string& html, const std::string& png,
                               const std::optional<int>& threads);

}  // namespace nurbsreg::python
