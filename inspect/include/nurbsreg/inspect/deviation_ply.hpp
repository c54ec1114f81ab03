#pragma once
// The coloured scan of an inspection (CONTRACT.md §2 "Inspection": D/deviations.ply), for
// CloudCompare, MeshLab, Open3D and the project's own reader.
//
// Binary little-endian PLY, one `element vertex` per inspected point, in scan order:
//   float x y z            aligned point (model coordinates)
//   uchar red green blue   the colour map's colour
//   float signed_distance  > 0 on the face's outer side
//   int   face             surface index in the model
//   double u v             foot parameters on that face
//   int   tolerance        -1 below the band, 0 inside, +1 above
//   int   index            0-based position of the point in the scan file
//   float quality          = signed_distance (MeshLab shows per-vertex quality as a scalar field)
//   float scalar_signed_distance  = signed_distance: CloudCompare loads a `scalar_*` property as
//                          a scalar field without asking (also from its command line, -SILENT);
//                          the other properties it offers in its PLY dialog
// Only types Open3D's reader knows (float, double, int, uchar), so it sees every field too.
// Writes atomically (io::write_atomically); throws io::OutputError. Streams in fixed-size
// blocks: no allocation per point.

#include <string>

#include "nurbsreg/inspect/colour_map.hpp"
#include "nurbsreg/inspect/deviations.hpp"

namespace nurbsreg::inspect {

void write_deviation_ply(const std::string& path, const PointDeviations& deviations,
                         const ColourScale& scale);

}  // namespace nurbsreg::inspect
