// `nurbsreg info --model M`: what a model holds (CONTRACT.md §1).

#include <spdlog/fmt/fmt.h>

#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "common.hpp"
#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/decompose.hpp"

namespace nurbsreg::cli {
namespace {

struct EntityInfo {
  std::string kind;
  std::string name;
  std::string degree;
  std::string control_points;
  bool rational = false;
  std::size_t bezier = 0;
  std::string domain;
  engine::Aabb box;
};

std::string format_box(const engine::Aabb& b) {
  return fmt::format("[{:.6g}, {:.6g}, {:.6g}] .. [{:.6g}, {:.6g}, {:.6g}]", b.lo.x(), b.lo.y(),
                     b.lo.z(), b.hi.x(), b.hi.y(), b.hi.z());
}

nlohmann::json box_json(const engine::Aabb& b) {
  return {{"min", {b.lo.x(), b.lo.y(), b.lo.z()}}, {"max", {b.hi.x(), b.hi.y(), b.hi.z()}}};
}

std::vector<EntityInfo> describe(const engine::Model& model) {
  std::vector<EntityInfo> out;
  for (const engine::NurbsSurface& s : model.surfaces) {
    EntityInfo e{"surface",
                 s.name,
                 fmt::format("{}x{}", s.degree_u, s.degree_v),
                 fmt::format("{}x{}", s.count_u, s.count_v),
                 s.is_rational(),
                 0,
                 "",
                 {}};
    const auto patches = engine::decompose(s);
    e.bezier = patches.size();
    for (const auto& patch : patches)
      e.box.extend(engine::bounding_box(patch));
    e.domain = fmt::format("u [{:.6g}, {:.6g}] v [{:.6g}, {:.6g}]", s.domain_u().lo,
                           s.domain_u().hi, s.domain_v().lo, s.domain_v().hi);
    out.push_back(std::move(e));
  }
  for (const engine::NurbsCurve& c : model.curves) {
    EntityInfo e{"curve",
                 c.name,
                 fmt::format("{}", c.degree),
                 fmt::format("{}", c.count()),
                 c.is_rational(),
                 0,
                 "",
                 {}};
    const auto pieces = engine::decompose(c);
    e.bezier = pieces.size();
    for (const auto& piece : pieces)
      e.box.extend(engine::bounding_box(piece));
    e.domain = fmt::format("u [{:.6g}, {:.6g}]", c.domain().lo, c.domain().hi);
    if (c.dimension == 2) e.kind = "curve (2-D)";
    out.push_back(std::move(e));
  }
  return out;
}

void run_info(const std::string& model_path, bool as_json) {
  const engine::Model model = load_model_file(model_path);
  const std::vector<EntityInfo> entities = describe(model);
  engine::Aabb all;
  std::size_t patches = 0;
  std::size_t pieces = 0;
  for (const EntityInfo& e : entities) {
    all.extend(e.box);
    (e.kind == "surface" ? patches : pieces) += e.bezier;
  }
  if (as_json) {
    nlohmann::json doc;
    doc["model"] = model_path;
    doc["units"] = model.units;
    doc["surfaces"] = nlohmann::json::array();
    doc["curves"] = nlohmann::json::array();
    for (const EntityInfo& e : entities) {
      nlohmann::json j = {
          {"name", e.name},         {"degree", e.degree}, {"control_points", e.control_points},
          {"rational", e.rational}, {"domain", e.domain}, {"bounding_box", box_json(e.box)}};
      if (e.kind == "surface") {
        j["bezier_patches"] = e.bezier;
        doc["surfaces"].push_back(j);
      } else {
        j["bezier_pieces"] = e.bezier;
        doc["curves"].push_back(j);
      }
    }
    doc["bezier_patches"] = patches;
    doc["bezier_pieces"] = pieces;
    doc["bounding_box"] = box_json(all);
    std::cout << doc.dump(2) << "\n";
    return;
  }
  std::cout << fmt::format("model {}  (units: {})\n", model_path, model.units);
  std::cout << fmt::format("{} surfaces, {} curves, {} Bézier patches, {} Bézier curve pieces\n",
                           model.surfaces.size(), model.curves.size(), patches, pieces);
  std::cout << "bounding box " << format_box(all) << "\n";
  std::size_t surface_index = 0;
  std::size_t curve_index = 0;
  for (const EntityInfo& e : entities) {
    const bool surface = e.kind == "surface";
    std::cout << fmt::format(
        "{} {} \"{}\": degree {}, control points {}, {}, {} Bézier {}, {}, box {}\n", e.kind,
        surface ? surface_index++ : curve_index++, e.name, e.degree, e.control_points,
        e.rational ? "rational" : "non-rational", e.bezier, surface ? "patches" : "pieces",
        e.domain, format_box(e.box));
  }
}

}  // namespace

void add_info_command(CLI::App& app) {
  auto* cmd =
      app.add_subcommand("info", "Surfaces, curves, degrees, Bézier patch count, bounding box");
  auto model = std::make_shared<std::string>();
  auto as_json = std::make_shared<bool>(false);
  cmd->add_option("--model", *model, "Model file (.json)")->required();
  cmd->add_flag("--json", *as_json, "Machine-readable JSON on stdout");
  cmd->callback([model, as_json] { run_info(*model, *as_json); });
}

}  // namespace nurbsreg::cli
