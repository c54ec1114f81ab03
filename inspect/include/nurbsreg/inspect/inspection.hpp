#pragma once
// A whole inspection after the pose is known: the statistics of the deviations, then every
// output file (CONTRACT.md §2 "Inspection") into an OutputFolder:
//   inspect.json, inspect_faces.csv, deviations.ply, report.html, deviations.png.
// The caller commits the folder. Writers run concurrently (tbb::parallel_invoke); the results do
// not depend on the thread count.

#include <cstddef>
#include <string>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/inspect/colour_map.hpp"
#include "nurbsreg/inspect/deviations.hpp"
#include "nurbsreg/inspect/inspection_report.hpp"
#include "nurbsreg/inspect/output_folder.hpp"
#include "nurbsreg/inspect/picture.hpp"
#include "nurbsreg/inspect/statistics.hpp"

namespace nurbsreg::inspect {

struct InspectionOptions {
  ColourScale scale;  // its band is the tolerance
  double min_inside = 0.99;
  std::size_t viewer_points = 300'000;
  bool model_mesh = true;  // the model's faces in grey in the report and the picture
  std::size_t mesh_vertices = 100'000;
  int histogram_bins = 64;
  PictureOptions picture;
};

// Where run_inspection writes; an empty path is not written.
struct InspectionOutputs {
  std::string ply, png, html, json, csv;
  // The five files of `nurbsreg inspect` in `folder` (CONTRACT.md §2 "Inspection").
  static InspectionOutputs in(const OutputFolder& folder);
};

// `report` carries the alignment part (model and scan names, units, alignment, pose_given,
// degeneracy, scan_points, alignment_seconds); the rest is filled in and returned.
InspectionReport run_inspection(const engine::PreparedModel& model,
                                const PointDeviations& deviations, InspectionReport report,
                                const InspectionOptions& options, const OutputFolder& folder);
// The same statistics, writing only the files `outputs` names (no mesh when neither the page nor
// the picture is asked for).
InspectionReport run_inspection(const engine::PreparedModel& model,
                                const PointDeviations& deviations, InspectionReport report,
                                const InspectionOptions& options, const InspectionOutputs& outputs);

// The alignment part of a report for a pose given as final (`inspect --pose`): no alignment
// ran; the rms is that of the deviations.
io::AlignmentReport given_pose_alignment(const Eigen::Matrix4d& pose,
                                         const PointDeviations& deviations,
                                         std::size_t scan_points);

}  // namespace nurbsreg::inspect
