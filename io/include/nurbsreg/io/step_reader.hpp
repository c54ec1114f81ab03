#pragma once
// B-spline surfaces from STEP files (ISO 10303-21 exchange structure, AP203/AP214/AP242).
//
// What is imported: every B-spline surface that is the geometry of a face (ADVANCED_FACE or
// FACE_SURFACE), in the order of the faces, each surface once even if several faces share it.
// Both encodings ISO 10303-42 allows are read: the simple B_SPLINE_SURFACE_WITH_KNOTS entity,
// and the complex instance (B_SPLINE_SURFACE + B_SPLINE_SURFACE_WITH_KNOTS
// [+ RATIONAL_B_SPLINE_SURFACE weights]) that CAD systems write for rational surfaces. Knot
// multiplicities are expanded; the knots need not be clamped. A file whose B-spline surfaces
// belong to no face (bare geometry) imports all of them. The model's units come from the
// file's LENGTH_UNIT (SI prefixes -> "mm", "cm", "m", "um", "km"; conversion-based units by
// their name, e.g. "inch").
//
// What is not: face trimming (edge loops) is ignored, so each face is represented by its whole
// underlying surface; analytic faces (planes, cylinders, cones, spheres, tori, surfaces of
// revolution or extrusion, offsets) are skipped and counted in StepImportReport; curves are not
// imported (edge curves are trimming geometry, not model curves).
//
// Errors: unreadable or malformed files, a referenced entity that is missing or of the wrong
// type, and B-spline surfaces that fail engine validation throw InputError naming the file and
// the entity, e.g. `part.step: #539 B_SPLINE_SURFACE_WITH_KNOTS: knots_u: decreasing at index 4`.
// Thread-safe (no shared state); allocates (load-time code).

#include <cstddef>
#include <map>
#include <string>
#include <string_view>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::io {

struct StepImportReport {
  std::size_t faces = 0;          // ADVANCED_FACE and FACE_SURFACE entities
  std::size_t bspline_faces = 0;  // faces whose geometry was imported
  std::size_t rational_surfaces = 0;
  std::map<std::string, std::size_t> skipped_faces;  // surface entity type -> face count
  std::string units_source;  // the STEP unit entity the units came from, or "" (default kept)
};

// Imports a STEP file. `report`, when given, receives counts of what was imported and skipped.
engine::Model read_step(const std::string& path, StepImportReport* report = nullptr);
engine::Model parse_step(std::string_view text, const std::string& file_label,
                         StepImportReport* report = nullptr);

}  // namespace nurbsreg::io
