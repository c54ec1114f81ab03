#pragma once
// Files of `nurbsreg modify` (curve modification, seed paper 004):
//  - the targets CSV: header `segment,x,y,z` (columns by name, any order, `z` optional and 0 when
//    absent, other columns ignored), one row per segment to move; `segment` is the 0-based index
//    of the curve's non-empty knot span; `#` starts a comment, blank lines are skipped;
//  - targets taken from a scan: the scanned point nearest to each nose point (exact kd-tree
//    search with FLANN; FLANN stays inside io, the engine never sees it);
//  - the report: JSON with the nose-point errors before and after every step (the paper's
//    Tables 1-2) and the improvement efficiency rho (eq. 22) of each step.
// All functions are thread-safe (no shared state); they allocate freely (not hot paths).

#include <span>
#include <string>
#include <vector>

#include "nurbsreg/engine/curve_modification.hpp"

namespace nurbsreg::io {

// Reads a targets CSV. Throws InputError naming the file and the line: missing header columns,
// a segment that is not a non-negative integer, a non-finite coordinate, a repeated segment, or
// no rows. Segment indices are not checked against a curve here (modify_curve does that).
std::vector<engine::SegmentTarget> read_modify_targets(const std::string& path);

// For every nose point, the nearest point of `scan` (Euclidean, exact; ties -> lowest index).
// Throws InputError(scan_label, ...) when the scan has no points.
std::vector<engine::SegmentTarget> nearest_scan_targets(std::span<const engine::Vec3> scan,
                                                        std::span<const engine::NosePoint> noses,
                                                        const std::string& scan_label);

const char* to_string(engine::ModifyMethod method);
const char* to_string(engine::NoseRule rule);

struct ModifyReport {
  std::string model_file;
  std::string curve_name;
  std::string target_source;  // e.g. "targets.csv" or "scan.pcd (nearest of 12000 points)"
  engine::ModifyOptions options;
  std::vector<engine::SegmentTarget> targets;  // as given (before completion with held noses)
  engine::ModifyResult result;
};

// The report as JSON: {"curve", "model", "method", "nose_rule", "iterate", "rho_min",
// "targets": [{"segment", "point"}], "steps": [{"operation", "errors", "total", "rho",
// "weights", "knots", "note", "reverted"}], "initial_errors", "final_errors", "initial_total",
// "final_total", "termination"}.
std::string modify_report_to_json(const ModifyReport& report);

// Writes modify_report_to_json atomically; throws OutputError.
void write_modify_report(const std::string& path, const ModifyReport& report);

}  // namespace nurbsreg::io
