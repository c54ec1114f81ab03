// The JSON model format's trimmed-face extension (README.md, "Model format: trimmed faces"):
// trim loops with uv curves and optional 3-D edges, face orientation, skipped faces. Bit-exact
// round trips, old files unchanged, and one malformed case per field naming its path.
#include <gtest/gtest.h>

#include <functional>
#include <nlohmann/json.hpp>

#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "support/model_parse_error.hpp"

namespace nurbsreg::io {
namespace {

using nlohmann::json;

using test::parse_error;

// A bilinear patch on [0, 1]^2 with a hole: outer loop of degree-1 uv lines (no edges needed),
// inner loop one rational quadratic circle in uv with its 3-D edge.
engine::Model trimmed_model() {
  engine::NurbsSurface s;
  s.name = "plate";
  s.degree_u = s.degree_v = 1;
  s.knots_u = s.knots_v = {0, 0, 1, 1};
  s.count_u = s.count_v = 2;
  s.control_points = {{0, 0, 0}, {0, 10, 0}, {10, 0, 0}, {10, 10, 0}};
  engine::TrimLoop outer;
  const engine::Vec3 corners[] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  for (int k = 0; k < 4; ++k) {
    engine::NurbsCurve line;
    line.degree = 1;
    line.dimension = 2;
    line.knots = {0, 0, 1, 1};
    line.control_points = {corners[k], corners[(k + 1) % 4]};
    outer.curves.push_back({line, std::nullopt});
  }
  engine::NurbsCurve circle = engine::make_circle(engine::Vec3(0.5, 0.5, 0), 0.25);
  engine::NurbsCurve uv = circle;
  uv.dimension = 2;
  engine::NurbsCurve edge = circle;
  edge.name = "hole";
  edge.dimension = 3;
  for (engine::Vec3& p : edge.control_points)
    p *= 10;  // S(u, v) = (10 u, 10 v, 0): the circle's control net maps linearly
  engine::TrimLoop inner;
  inner.curves.push_back({uv, edge});
  s.trim_loops = {outer, inner};
  s.reversed = true;
  engine::Model m;
  m.surfaces.push_back(s);
  m.skipped_faces = {{3, "OCCT's NURBS conversion left a Geom_OffsetSurface"}};
  return m;
}

TEST(ModelJsonTrim, WriteThenReadIsBitExact) {
  const engine::Model m = trimmed_model();
  ASSERT_FALSE(m.validate().has_value()) << *m.validate();
  const std::string text = model_to_json(m);
  const engine::Model back = parse_model(text, "m.json");
  EXPECT_EQ(model_to_json(back), text);
  ASSERT_EQ(back.surfaces.size(), 1u);
  const engine::NurbsSurface& s = back.surfaces[0];
  EXPECT_TRUE(s.reversed);
  ASSERT_EQ(s.trim_loops.size(), 2u);
  EXPECT_EQ(s.trim_loops[0].curves.size(), 4u);
  EXPECT_FALSE(s.trim_loops[0].curves[0].edge.has_value());
  ASSERT_TRUE(s.trim_loops[1].curves[0].edge.has_value());
  EXPECT_EQ(s.trim_loops[1].curves[0].edge->name, "hole");
  EXPECT_EQ(s.trim_loops[1].curves[0].uv.dimension, 2);
  EXPECT_EQ(s.trim_loops[1].curves[0].uv.weights, m.surfaces[0].trim_loops[1].curves[0].uv.weights);
  ASSERT_EQ(back.skipped_faces.size(), 1u);
  EXPECT_EQ(back.skipped_faces[0].face, 3);
  EXPECT_EQ(back.skipped_faces[0].reason, m.skipped_faces[0].reason);
}

TEST(ModelJsonTrim, UntrimmedModelsAreWrittenAsBefore) {
  engine::Model m;
  m.surfaces.push_back(engine::make_torus(engine::Vec3(0, 0, 0), 3, 1));
  const std::string text = model_to_json(m);
  EXPECT_EQ(text.find("trim_loops"), std::string::npos);
  EXPECT_EQ(text.find("reversed"), std::string::npos);
  EXPECT_EQ(text.find("skipped_faces"), std::string::npos);
  const engine::Model back = parse_model(text, "m.json");
  EXPECT_FALSE(back.surfaces[0].is_trimmed());
  EXPECT_FALSE(back.surfaces[0].reversed);
}

// Each case edits the valid trimmed document and expects these words in the message.
TEST(ModelJsonTrim, ErrorsNameTheFieldPath) {
  const json valid = json::parse(model_to_json(trimmed_model()));
  ASSERT_EQ(parse_error(valid.dump()), "");
  struct Case {
    std::function<void(json&)> edit;
    std::string expected;
  };
  const auto surface = [](json& d) -> json& { return d["surfaces"][0]; };
  const std::vector<Case> cases = {
      {[&](json& d) { surface(d)["trim_loops"] = 3; },
       "surface 0 \"plate\": trim_loops: expected an array"},
      {[&](json& d) { surface(d)["trim_loops"][0] = json::array(); },
       "trim_loops[0]: expected an object"},
      {[&](json& d) { surface(d)["trim_loops"][0].erase("curves"); },
       "trim_loops[0].curves: missing"},
      {[&](json& d) { surface(d)["trim_loops"][0]["curves"] = json::array(); },
       "trim_loops[0].curves: a loop needs at least one curve"},
      {[&](json& d) { surface(d)["trim_loops"][1]["curves"][0].erase("uv"); },
       "trim_loops[1].curves[0].uv: missing"},
      {[&](json& d) { surface(d)["trim_loops"][1]["curves"][0]["uv"]["knots"][3] = -5; },
       "trim_loops[1].curves[0].uv \"circle\": knots: decreasing"},
      {[&](json& d) {
         surface(d)["trim_loops"][1]["curves"][0]["edge"]["weights"] = {1, 2};
       },
       "trim_loops[1].curves[0].edge \"hole\": weights: expected 9 values"},
      {[&](json& d) { surface(d)["trim_loops"][1]["curves"][0].erase("edge"); },
       "needs its 3-D edge"},
      {[&](json& d) {
         for (json& p : surface(d)["trim_loops"][0]["curves"][0]["uv"]["control_points"])
           p.push_back(0);
       },
       "trim_loops[0].curves[0].uv: must be a 2-D curve"},
      {[&](json& d) { surface(d)["reversed"] = "yes"; }, "reversed: expected true or false"},
      {[&](json& d) { d["skipped_faces"] = json::object(); }, "skipped_faces: expected an array"},
      {[&](json& d) { d["skipped_faces"][0]["face"] = -1; }, "skipped_faces[0].face: must be >= 0"},
      {[&](json& d) { d["skipped_faces"][0].erase("reason"); }, "skipped_faces[0].reason: missing"},
      {[&](json& d) { d["skipped_faces"][0]["reason"] = 7; },
       "skipped_faces[0].reason: expected a string"},
  };
  for (const Case& c : cases) {
    json document = valid;
    c.edit(document);
    const std::string message = parse_error(document.dump());
    EXPECT_NE(message.find(c.expected), std::string::npos)
        << "expected \"" << c.expected << "\" in \"" << message << "\"";
  }
}

}  // namespace
}  // namespace nurbsreg::io
