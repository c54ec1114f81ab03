#include "nurbsreg/io/model_summary.hpp"

#include <nlohmann/json.hpp>

#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/prepared_model.hpp"
#include "text_io.hpp"

namespace nurbsreg::io {
namespace {

std::string number(double x) {
  std::string s;
  text_detail::append_number(s, x);
  return s;
}

std::string point(const engine::Vec3& p) {
  return "(" + number(p.x()) + ", " + number(p.y()) + ", " + number(p.z()) + ")";
}

std::string label(const char* kind, const EntitySummary& e) {
  std::string s = std::string(kind) + " " + std::to_string(e.index);
  if (!e.name.empty()) s += " " + nlohmann::json(e.name).dump();
  return s;
}

nlohmann::ordered_json box_json(const engine::Aabb& box) {
  if (box.empty()) return nullptr;
  return {{"min", {box.lo.x(), box.lo.y(), box.lo.z()}},
          {"max", {box.hi.x(), box.hi.y(), box.hi.z()}}};
}

}  // namespace

ModelSummary summarize_model(const engine::Model& model) {
  // The trimmed geometry's boxes need the prepared form (trim regions, edges).
  return summarize_model(model, engine::PreparedModel(model));
}

// The entities as the file gives them (`model`: the prepared form's own copy holds the faces
// trimmed to a rectangle as untrimmed surfaces), the trimmed boxes from `prepared`.
ModelSummary summarize_model(const engine::Model& model, const engine::PreparedModel& prepared) {
  ModelSummary summary;
  summary.units = model.units;
  for (std::size_t k = 0; k < model.surfaces.size(); ++k) {
    const engine::NurbsSurface& s = model.surfaces[k];
    EntitySummary e;
    e.index = k;
    e.name = s.name;
    e.degree_u = s.degree_u;
    e.degree_v = s.degree_v;
    e.count_u = s.count_u;
    e.count_v = s.count_v;
    e.rational = s.is_rational();
    e.domain_u = s.domain_u();
    e.domain_v = s.domain_v();
    e.trim_loops = s.trim_loops.size();
    for (const engine::TrimLoop& loop : s.trim_loops)
      e.trim_curves += loop.curves.size();
    e.reversed = s.reversed;
    summary.trimmed_surfaces += s.is_trimmed() ? 1 : 0;
    const std::vector<engine::BezierPatch> patches = engine::decompose(s);
    e.bezier_pieces = patches.size();
    for (const engine::BezierPatch& patch : patches)
      e.box.extend(engine::bounding_box(patch));
    summary.bezier_patches += e.bezier_pieces;
    summary.box.extend(e.box);
    summary.surfaces.push_back(std::move(e));
  }
  for (std::size_t k = 0; k < model.curves.size(); ++k) {
    const engine::NurbsCurve& c = model.curves[k];
    EntitySummary e;
    e.index = k;
    e.name = c.name;
    e.degree_u = c.degree;
    e.count_u = c.count();
    e.count_v = 1;
    e.rational = c.is_rational();
    e.domain_u = c.domain();
    e.domain_v = {0.0, 0.0};
    const std::vector<engine::BezierCurve> pieces = engine::decompose(c);
    e.bezier_pieces = pieces.size();
    for (const engine::BezierCurve& piece : pieces)
      e.box.extend(engine::bounding_box(piece));
    summary.bezier_curve_pieces += e.bezier_pieces;
    summary.box.extend(e.box);
    summary.curves.push_back(std::move(e));
  }
  summary.skipped_faces = model.skipped_faces;
  summary.geometry = prepared.geometry_bounds();
  for (std::size_t k = 0; k < summary.surfaces.size(); ++k) {
    summary.surfaces[k].geometry = engine::compute_surface_bounds(prepared, static_cast<int>(k));
    summary.surfaces[k].trimmed_to_rectangle = prepared.rectangle_face(static_cast<int>(k));
    summary.surfaces[k].search_patches = prepared.surface_patch_count(static_cast<int>(k));
    summary.search_patches += summary.surfaces[k].search_patches;
  }
  for (EntitySummary& e : summary.curves) {
    e.geometry.box = e.geometry.witnessed = e.box;
    e.geometry.exact = false;
  }
  return summary;
}

std::string format_model_summary(const ModelSummary& m, const std::string& model_label) {
  std::size_t rational_surfaces = 0;
  std::size_t rational_curves = 0;
  for (const auto& e : m.surfaces)
    rational_surfaces += e.rational ? 1 : 0;
  for (const auto& e : m.curves)
    rational_curves += e.rational ? 1 : 0;
  std::string out = "model: " + model_label + " (units " + m.units + ")\n";
  out +=
      "surfaces: " + std::to_string(m.surfaces.size()) + " (" + std::to_string(rational_surfaces) +
      " rational" +
      (m.trimmed_surfaces > 0 ? ", " + std::to_string(m.trimmed_surfaces) + " trimmed" : "") +
      "), Bézier patches: " + std::to_string(m.bezier_patches) +
      (m.search_patches != m.bezier_patches ? " (searched as " + std::to_string(m.search_patches) +
                                                  ": patches far from flat are cut finer)"
                                            : "") +
      "\n";
  for (const auto& e : m.surfaces) {
    out += "  " + label("surface", e) + ": degree (" + std::to_string(e.degree_u) + ", " +
           std::to_string(e.degree_v) + "), " + std::to_string(e.count_u) + " x " +
           std::to_string(e.count_v) + " control points, " +
           (e.rational ? "rational" : "polynomial") + ", " + std::to_string(e.bezier_pieces) +
           " Bézier patches" +
           (e.search_patches != e.bezier_pieces
                ? " (searched as " + std::to_string(e.search_patches) + ")"
                : "") +
           ", u [" + number(e.domain_u.lo) + ", " + number(e.domain_u.hi) + "], v [" +
           number(e.domain_v.lo) + ", " + number(e.domain_v.hi) + "]";
    if (e.trim_loops > 0) {
      out += ", trimmed (" + std::to_string(e.trim_loops) + " loops, " +
             std::to_string(e.trim_curves) + " curves" +
             (e.trimmed_to_rectangle ? ": a rectangle of its domain, projected untrimmed" : "") +
             ")";
    }
    out += e.reversed ? ", reversed\n" : "\n";
  }
  out += "curves: " + std::to_string(m.curves.size()) + " (" + std::to_string(rational_curves) +
         " rational), Bézier pieces: " + std::to_string(m.bezier_curve_pieces) + "\n";
  for (const auto& e : m.curves) {
    out += "  " + label("curve", e) + ": degree " + std::to_string(e.degree_u) + ", " +
           std::to_string(e.count_u) + " control points, " +
           (e.rational ? "rational" : "polynomial") + ", " + std::to_string(e.bezier_pieces) +
           " Bézier pieces, u [" + number(e.domain_u.lo) + ", " + number(e.domain_u.hi) + "]\n";
  }
  if (!m.skipped_faces.empty()) {
    out += "skipped faces: " + std::to_string(m.skipped_faces.size()) + "\n";
    for (const engine::SkippedFace& f : m.skipped_faces)
      out += "  skipped face " + std::to_string(f.face) + ": " + f.reason + "\n";
  }
  const engine::ModelBounds& g = m.geometry;
  if (g.box.empty()) {
    out += "bounding box: empty (every face is trimmed away)\n";
  } else {
    out +=
        "bounding box: " + point(g.box.lo) + " .. " + point(g.box.hi) + ", diagonal " +
        number(g.box.diagonal()) + " " + m.units + " (of the faces as trimmed, " +
        (g.exact ? std::string("exact")
                 : "proven bound: at most " + number(g.excess) + " " + m.units + " beyond them") +
        ")\n";
  }
  if (!m.box.empty()) {
    out += "control-point box (untrimmed surfaces): " + point(m.box.lo) + " .. " + point(m.box.hi) +
           ", diagonal " + number(m.box.diagonal()) + " " + m.units + "\n";
  }
  return out;
}

std::string model_summary_to_json(const ModelSummary& m) {
  using Json = nlohmann::ordered_json;
  const auto entity = [](const EntitySummary& e, bool surface) {
    Json j{{"index", e.index}, {"name", e.name}};
    if (surface) {
      j["degree"] = {e.degree_u, e.degree_v};
      j["control_points"] = {e.count_u, e.count_v};
      j["bezier_patches"] = e.bezier_pieces;
      j["domain"] = {{e.domain_u.lo, e.domain_u.hi}, {e.domain_v.lo, e.domain_v.hi}};
      j["trimmed"] = e.trim_loops > 0;
      j["trim_loops"] = e.trim_loops;
      j["trim_curves"] = e.trim_curves;
      j["trimmed_to_rectangle"] = e.trimmed_to_rectangle;
      j["search_patches"] = e.search_patches;
      j["reversed"] = e.reversed;
    } else {
      j["degree"] = e.degree_u;
      j["control_points"] = e.count_u;
      j["bezier_pieces"] = e.bezier_pieces;
      j["domain"] = {e.domain_u.lo, e.domain_u.hi};
    }
    j["rational"] = e.rational;
    if (surface) {
      j["bounding_box"] = box_json(e.geometry.box);
      j["bounding_box_kind"] = e.geometry.kind();
      j["bounding_box_excess"] = e.geometry.excess;
      j["control_point_box"] = box_json(e.box);
    } else {
      j["bounding_box"] = box_json(e.box);
    }
    return j;
  };
  Json surfaces = Json::array();
  for (const auto& e : m.surfaces)
    surfaces.push_back(entity(e, true));
  Json curves = Json::array();
  for (const auto& e : m.curves)
    curves.push_back(entity(e, false));
  Json skipped = Json::array();
  for (const engine::SkippedFace& f : m.skipped_faces)
    skipped.push_back(Json{{"face", f.face}, {"reason", f.reason}});
  const Json j{{"units", m.units},
               {"surfaces", std::move(surfaces)},
               {"curves", std::move(curves)},
               {"bezier_patches", m.bezier_patches},
               {"search_patches", m.search_patches},
               {"bezier_curve_pieces", m.bezier_curve_pieces},
               {"bounding_box", box_json(m.geometry.box)},
               {"bounding_box_kind", m.geometry.kind()},
               {"bounding_box_excess", m.geometry.excess},
               {"control_point_box", box_json(m.box)},
               {"trimmed_surfaces", m.trimmed_surfaces},
               {"skipped_faces", std::move(skipped)}};
  return j.dump(2) + "\n";
}

}  // namespace nurbsreg::io
