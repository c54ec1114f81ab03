#pragma once
// The deviation map as a picture (D/deviations.png) for e-mail and documents: every inspected
// point drawn from a fixed viewpoint over the model's faces in grey, with the colour legend,
// the tolerance and the summary numbers. Rendered by the program itself (a z-buffer rasteriser
// for the model and the points, cairo for the legend's text and the PNG), so it looks the same
// on every machine.
//
// The viewpoint is fixed so pictures of different scans of one part compare: orthographic,
// looking from the +X -Y +Z octant towards the centre of the scan (the isometric direction),
// +Z up on the page. Allocates the image (width x height); serial and deterministic.

#include <string>

#include "nurbsreg/engine/types.hpp"
#include "nurbsreg/inspect/colour_map.hpp"
#include "nurbsreg/inspect/deviations.hpp"
#include "nurbsreg/inspect/inspection_report.hpp"
#include "nurbsreg/inspect/tessellation.hpp"

namespace nurbsreg::inspect {

struct ViewDirection {
  engine::Vec3 eye;  // unit vector from the target to the eye
  engine::Vec3 up;   // unit, orthogonal to eye
  std::string description;
};

// The fixed viewpoint of the picture and the report's first view.
ViewDirection isometric_view();

struct PictureOptions {
  int width = 1600;
  int height = 1000;
};

// Writes the PNG atomically (io::write_atomically); throws io::OutputError.
void write_deviation_picture(const std::string& path, const PointDeviations& deviations,
                             const DisplayMesh& mesh, const InspectionReport& report,
                             const PictureOptions& options = {});

}  // namespace nurbsreg::inspect
