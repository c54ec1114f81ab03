#pragma once
// STEP and IGES models through OpenCASCADE (OCCT stays private to io: no OCCT type here).
//
// What is imported: every face of the file's shape, in OCCT's face order
// (TopExp::MapShapes(shape, TopAbs_FACE): face index = map index - 1), as an exact NURBS
// surface -- analytic faces too (planes, cylinders, cones, spheres, tori, revolutions,
// extrusions become rational B-splines through BRepBuilderAPI_NurbsConvert) -- with its trim
// loops: every wire of the face, each edge as its 2-D parameter-space curve ("uv") and its 3-D
// curve ("edge", same parameter domain; a degenerated edge at a pole is a constant curve at
// the pole; an edge farther than the tolerance below from S(uv(t)) is replaced by S(uv(t))
// approximated within it, so that edge(t) and uv(t) agree). On a periodic surface the wires are
// made continuous across the seam (curves translated by whole periods) and the surface is
// repeated over the periods they span, so that the whole face is in its domain. A face whose
// orientation is REVERSED gets `reversed = true`. Geometry of degree above engine::kMaxDegree is
// approximated within 1e-9 x the model's diagonal when OCCT can (counted in the report); a face
// that still cannot be converted is recorded in Model::skipped_faces with its index and the
// reason, never dropped silently. Surfaces are named "face <index>".
//
// Units: OCCT converts lengths to millimetres, so Model::units is always "mm"; the file's own
// length unit is reported in CadImportReport::file_units when the reader exposes it.
//
// Errors: a file OCCT cannot read (missing, empty, garbage, truncated), one without faces, or
// one none of whose faces converts throws InputError naming the file and what is wrong.
// Thread-safe (OCCT's data-exchange readers share global state, so imports are serialised).

#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::io {

struct CadImportReport {
  std::string format;              // "STEP" or "IGES"
  std::string file_units;          // the file's length unit as it names it ("MM", "INCH"...), or ""
  std::size_t faces = 0;           // faces of the file's shape
  std::size_t trimmed_faces = 0;   // converted faces with trim loops
  std::size_t analytic_faces = 0;  // converted faces whose surface was not a B-spline
  std::size_t approximations = 0;  // surfaces and curves approximated to degree <= kMaxDegree
  std::size_t degenerated_edges = 0;
  // 3-D edges replaced by their exact image S(uv(t)), approximated within the tolerance,
  // because the file's curve was farther than that from it (CAD edges are only within their
  // own tolerance, often 1e-7..1e-3 mm); and edges kept although off by more (no approximation).
  std::size_t rebuilt_edges = 0;
  std::size_t inconsistent_edges = 0;
  // uv curves that leave their surface's parameter domain (OCCT extrapolates the surface there,
  // the engine clamps), after periodic ones are shifted back by whole periods.
  std::size_t uv_outside_domain = 0;
  std::map<std::string, std::size_t> surface_types;  // OCCT surface type of each face -> count
  // Model::surfaces[k] is face surface_faces[k] of the file.
  std::vector<int> surface_faces;
  double diagonal = 0;  // of the shape's bounding box, in mm
};

// Dispatches on the extension: .step/.stp or .iges/.igs (case-insensitive).
engine::Model read_cad_file(const std::string& path, CadImportReport* report = nullptr);
engine::Model read_step(const std::string& path, CadImportReport* report = nullptr);
engine::Model read_iges(const std::string& path, CadImportReport* report = nullptr);

}  // namespace nurbsreg::io
