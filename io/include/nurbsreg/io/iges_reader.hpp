#pragma once
// B-spline surfaces from IGES files (Initial Graphics Exchange Specification 5.3, fixed-format
// ASCII: Start, Global, Directory Entry, Parameter Data and Terminate sections).
//
// What is imported: every Rational B-Spline Surface entity (type 128), in directory order,
// with its transformation matrix (type 124, chained) applied to the control points. Knots,
// weights and control points follow IGES 5.3 §4.24: the first (u) index varies fastest in the
// parameter data; they are stored here with i along u as everywhere in nurbsreg. Weights are
// dropped when the entity declares itself polynomial (PROP3 = 1). The model's units come from
// the Global section's unit flag (1 inch, 2 mm, 4 foot, 6 m, 10 cm, ...; 3 = the named unit).
//
// What is not: trimming (types 141-144 boundaries) is ignored, so a trimmed face is represented
// by its whole underlying surface; a surface's own parameter range (U0, U1, V0, V1) narrower
// than its knot domain is not applied (exporters write the knot domain in practice); other
// surface types are skipped and counted; the compressed ASCII and binary forms are rejected.
//
// Errors throw InputError naming the file and the line or the entity, e.g.
// `part.igs: DE 7 (type 128): weights[3][0]: must be a finite number > 0 (got 0)`.
// Thread-safe (no shared state); allocates (load-time code).

#include <cstddef>
#include <map>
#include <string>
#include <string_view>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::io {

struct IgesImportReport {
  std::size_t entities = 0;                   // directory entries
  std::size_t bspline_surfaces = 0;           // type 128 imported
  std::size_t rational_surfaces = 0;          // of which rational
  std::size_t transformed = 0;                // of which had a transformation matrix applied
  std::map<int, std::size_t> other_surfaces;  // other surface entity types -> count
};

engine::Model read_iges(const std::string& path, IgesImportReport* report = nullptr);
engine::Model parse_iges(std::string_view text, const std::string& file_label,
                         IgesImportReport* report = nullptr);

}  // namespace nurbsreg::io
