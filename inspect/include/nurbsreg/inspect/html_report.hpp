#pragma once
// The inspection report for people (D/report.html): one self-contained file that works offline
// (no CDN, no network, nothing beside it): the verdict and summary numbers, an interactive
// WebGL view of the coloured scan (three.js, embedded into the nurbsreg binary at build time;
// orbit, zoom, pan, hover shows a point's deviation and face, the model's faces in grey), the
// colour legend, the histogram of signed deviations with the tolerance band (SVG), the sortable
// per-face table and the alignment.
//
// Every number on the page comes from the same InspectionReport as inspect.json, and each shown
// number carries its exact value in a data-value attribute (so tests and scripts can compare).
// The 3-D view shows the `subset` of the points (stated on the page); every statistic uses all.
// Writes atomically; throws io::OutputError. Allocates (the page is built in memory).

#include <string>

#include "nurbsreg/inspect/deviations.hpp"
#include "nurbsreg/inspect/inspection_report.hpp"
#include "nurbsreg/inspect/tessellation.hpp"
#include "nurbsreg/inspect/viewer_subset.hpp"

namespace nurbsreg::inspect {

std::string html_report(const InspectionReport& report, const PointDeviations& deviations,
                        const ViewerSubset& subset, const DisplayMesh& mesh);

void write_html_report(const std::string& path, const InspectionReport& report,
                       const PointDeviations& deviations, const ViewerSubset& subset,
                       const DisplayMesh& mesh);

}  // namespace nurbsreg::inspect
