#pragma once
// What `nurbsreg info` reports about a model (CONTRACT.md §1): surfaces and curves with their
// degrees, control-point counts, rationality and parameter domains; the number of Bézier
// patches (pieces for curves) the engine will cache; and a bounding box. For CAD models also
// each face's trimming (loops, curves) and orientation, and the faces that were skipped.
//
// Two boxes. `box` (per entity and overall) is the union of the Bézier patches' control-point
// boxes of the UNTRIMMED surfaces: it contains the model but, for a CAD face cut from a large
// surface, can be many times its size. `geometry` (per surface and overall) is the proven box of
// the trimmed faces, their edges and the curves (engine/model_bounds.hpp), exact or a proven
// bound at most `excess` beyond them: the model's size that `info` reports as its bounding box.
// summarize_model prepares the model once (allocates; load-time code), or uses the given
// PreparedModel made from it (and its geometry_bounds, computed once per model). Thread-safe.

#include <cstddef>
#include <string>
#include <vector>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/model.hpp"
#include "nurbsreg/engine/model_bounds.hpp"
#include "nurbsreg/engine/prepared_model.hpp"

namespace nurbsreg::io {

struct EntitySummary {
  std::size_t index = 0;  // position in Model::surfaces or Model::curves
  std::string name;
  int degree_u = 0;  // curves: the degree
  int degree_v = 0;  // curves: 0
  int count_u = 0;   // control points along u (curves: all of them)
  int count_v = 0;   // curves: 1
  bool rational = false;
  std::size_t bezier_pieces = 0;  // patches (surfaces) or pieces (curves)
  // Surfaces: the patches the engine searches (bezier_pieces, cut finer where they are far from
  // flat: engine::PreparedModel::surface_patch_count).
  std::size_t search_patches = 0;
  engine::ParamInterval domain_u;
  engine::ParamInterval domain_v;  // curves: [0, 0]
  engine::Aabb box;
  engine::ModelBounds geometry;  // surfaces: the trimmed face's box; curves: equal to `box`
  // Surfaces (CAD faces): trimming and orientation. Curves: 0 and false.
  std::size_t trim_loops = 0;
  std::size_t trim_curves = 0;
  // The trim loop cuts out a rectangle of the domain (iso-parametric sides): the engine projects
  // the face as that rectangle of its surface, untrimmed (engine::PreparedModel::rectangle_face).
  bool trimmed_to_rectangle = false;
  bool reversed = false;
};

struct ModelSummary {
  std::string units;
  std::vector<EntitySummary> surfaces;
  std::vector<EntitySummary> curves;
  std::size_t bezier_patches = 0;       // over all surfaces
  std::size_t search_patches = 0;       // over all surfaces
  std::size_t bezier_curve_pieces = 0;  // over all curves
  engine::Aabb box;                     // over everything (control points, untrimmed)
  engine::ModelBounds geometry;         // over everything: trimmed faces, edges, curves
  std::size_t trimmed_surfaces = 0;
  std::vector<engine::SkippedFace> skipped_faces;  // CAD faces that could not be converted
};

ModelSummary summarize_model(const engine::Model& model);
// `prepared` must have been made from `model`.
ModelSummary summarize_model(const engine::Model& model, const engine::PreparedModel& prepared);

// Human-readable, one line per entity, e.g.
//   surface 0 "hood": degree (3, 3), 7 x 6 control points, rational, 12 Bézier patches, ...
// then `skipped face 7: <reason>` lines.
std::string format_model_summary(const ModelSummary& summary, const std::string& model_label);

// The same as a JSON object (for scripts): {"units", "surfaces": [...], "curves": [...],
// "bezier_patches", "bezier_curve_pieces", "bounding_box": {"min": [..], "max": [..]},
// "bounding_box_kind": "exact" | "proven bound", "bounding_box_excess", "control_point_box",
// "trimmed_surfaces", "skipped_faces": [{"face", "reason"}]}; each surface also has "trimmed",
// "trim_loops", "trim_curves", "reversed" and "search_patches" (also a total), and its
// "bounding_box" is its trimmed face's (with "bounding_box_kind", "bounding_box_excess" and
// "control_point_box").
std::string model_summary_to_json(const ModelSummary& summary);

}  // namespace nurbsreg::io
