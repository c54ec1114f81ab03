#pragma once
// What an inspection reports, and its forms for scripts: D/inspect.json (CONTRACT.md §2
// "Inspection": the alignment report's fields, "tolerance", the overall statistics at the top
// level, "faces") and D/inspect_faces.csv (one row per face and a first row for all points).
// Numbers are written in their shortest exact form; NaN (a face without points) as null in
// JSON and empty in CSV. Thread-safe; allocates (not a hot path).

#include <cstddef>
#include <optional>
#include <string>

#include "nurbsreg/inspect/colour_map.hpp"
#include "nurbsreg/inspect/statistics.hpp"
#include "nurbsreg/io/alignment_report.hpp"

namespace nurbsreg::inspect {

struct InspectionReport {
  std::string model_file, scan_file;
  std::string units;
  // The alignment (or the given pose, with iterations 0 and `pose_given`).
  io::AlignmentReport alignment;
  bool pose_given = false;
  std::string degeneracy;       // the pose's free directions; empty when fully constrained
  std::size_t scan_points = 0;  // finite points of the scan file
  InspectionStatistics stats;
  ColourScale scale;
  // Pass when at least this fraction of the points lies inside the tolerance.
  double min_inside = 0.99;
  // The viewer's subset (HTML) and how it was chosen.
  std::size_t viewer_points = 0;
  std::string viewer_subset;
  std::string picture_view;  // the PNG's viewpoint, in words
  double alignment_seconds = 0.0;
  // Statistics, viewer subset, mesh, PLY and picture (the page and the JSON that state it are
  // written after).
  double inspection_seconds = 0.0;

  bool passed() const {
    return stats.overall.points > 0 && stats.overall.inside_fraction() >= min_inside;
  }
};

std::string inspection_json(const InspectionReport& report);
std::string faces_csv(const InspectionReport& report);

}  // namespace nurbsreg::inspect
