// Model JSON: the reader against independently published NURBS values (geomdl, tinynurbs), exact
// write -> read round trips, and one test per malformed-input class checking that the message
// names the file, the entity and the field.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "support/model_parse_error.hpp"
#include "support/random_entities.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::io {
namespace {

using engine::Model;
using engine::NurbsCurve;
using engine::NurbsSurface;
using engine::Vec3;
using nlohmann::json;

std::filesystem::path temp_dir() {
  const auto dir = std::filesystem::path(::testing::TempDir()) / "nurbsreg_io_model_json";
  std::filesystem::create_directories(dir);
  return dir;
}

using test::parse_error;

// The public test cases, converted to the contract's model format by this test (not by the
// reader under test): degree_u/degree_v -> degree [p, q], ctrlpts -> control_points.
json to_model_document(const json& c) {
  json entity;
  entity["name"] = c["id"];
  if (c["type"] == "curve") {
    entity["degree"] = c["degree"];
    entity["knots"] = c["knots"];
  } else {
    entity["degree"] = {c["degree_u"], c["degree_v"]};
    entity["knots_u"] = c["knots_u"];
    entity["knots_v"] = c["knots_v"];
  }
  entity["control_points"] = c["ctrlpts"];
  if (c.contains("weights")) entity["weights"] = c["weights"];
  json document = {{"nurbsreg_model", 1}, {"units", "mm"}};
  document[c["type"] == "curve" ? "curves" : "surfaces"] = json::array({entity});
  return document;
}

TEST(ModelJson, ReadsPublishedCasesWithTheirExpectedPoints) {
  const std::string path =
      nurbsreg::test::shared_dir() + "/data/real/numeric/nurbs_test_cases.json";
  std::ifstream in(path);
  ASSERT_TRUE(in) << "missing shared data: " << path;
  const json cases = json::parse(in)["cases"];
  int checked = 0;
  for (const json& c : cases) {
    if (!c.contains("evaluate") || (c["type"] != "curve" && c["type"] != "surface")) continue;
    SCOPED_TRACE(c["id"].get<std::string>());
    const Model model = parse_model(to_model_document(c).dump(), "case.json");
    const double tol = c.value("tol", 1e-12);
    for (const json& e : c["evaluate"]) {
      if (!e.contains("point")) continue;
      Vec3 expected = Vec3::Zero();
      for (std::size_t k = 0; k < e["point"].size(); ++k)
        expected[k] = e["point"][k];
      Vec3 got;
      if (c["type"] == "curve") {
        ASSERT_EQ(model.curves.size(), 1u);
        EXPECT_EQ(model.curves[0].dimension, static_cast<int>(e["point"].size()));
        got = model.curves[0].evaluate(e["u"]);
      } else {
        ASSERT_EQ(model.surfaces.size(), 1u);
        got = model.surfaces[0].evaluate(e["uv"][0], e["uv"][1]);
      }
      // geomdl prints 3-4 decimals: its own tolerance applies per coordinate.
      EXPECT_LE((got - expected).cwiseAbs().maxCoeff(), tol) << got.transpose();
      ++checked;
    }
  }
  // 2 B-spline curves, the rational curve, the bicubic surface, the circle, the hemisphere.
  EXPECT_GE(checked, 25);
}

TEST(ModelJson, SurfaceRowsRunAlongU) {
  // A 3 x 2 bilinear-in-v, quadratic-in-u net whose points encode (i, j): S(u, 0) must pass
  // through row i = 0..2 at j = 0, i.e. x varies with u, y with v.
  const std::string text = R"({"nurbsreg_model": 1, "surfaces": [{
      "degree": [2, 1], "knots_u": [0, 0, 0, 1, 1, 1], "knots_v": [0, 0, 1, 1],
      "control_points": [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]], [[2, 0, 0], [2, 1, 0]]]}]})";
  const Model m = parse_model(text, "m.json");
  const NurbsSurface& s = m.surfaces[0];
  EXPECT_EQ(s.count_u, 3);
  EXPECT_EQ(s.count_v, 2);
  EXPECT_FALSE(s.is_rational());
  EXPECT_EQ(m.units, "mm");
  EXPECT_LT((s.evaluate(1.0, 0.0) - Vec3(2, 0, 0)).norm(), 1e-15);
  EXPECT_LT((s.evaluate(0.0, 1.0) - Vec3(0, 1, 0)).norm(), 1e-15);
  EXPECT_LT((s.evaluate(0.5, 0.5) - Vec3(1, 0.5, 0)).norm(), 1e-15);
}

bool same_curve(const NurbsCurve& a, const NurbsCurve& b) {
  return a.name == b.name && a.degree == b.degree && a.dimension == b.dimension &&
         a.knots == b.knots && a.control_points == b.control_points && a.weights == b.weights;
}

bool same_surface(const NurbsSurface& a, const NurbsSurface& b) {
  return a.name == b.name && a.degree_u == b.degree_u && a.degree_v == b.degree_v &&
         a.knots_u == b.knots_u && a.knots_v == b.knots_v && a.count_u == b.count_u &&
         a.count_v == b.count_v && a.control_points == b.control_points && a.weights == b.weights;
}

Model mixed_model() {
  Model m;
  m.units = "m";
  m.surfaces.push_back(test::random_surface(11, 3, 3, 7, 6, /*rational=*/true));
  m.surfaces.push_back(test::random_surface(12, 5, 2, 9, 4, /*rational=*/false, /*clamped=*/false));
  m.surfaces.push_back(test::random_surface(13, 12, 1, 14, 2, /*rational=*/true));
  m.surfaces.push_back(engine::make_sphere(Vec3(1, 2, 3), 0.1));
  m.surfaces.push_back(engine::make_torus(Vec3(-1e6, 0, 1e-9), 3.0, 1.0 / 3.0));
  m.surfaces.back().name = "quoted \"name\" \\ with ünïcödé and\ttab";
  m.curves.push_back(test::random_curve(21, 3, 10, /*rational=*/true));
  m.curves.push_back(test::random_curve(22, 4, 8, /*rational=*/false, /*clamped=*/false, 2));
  m.curves.push_back(engine::make_circle(Vec3(0, 0, 5), 1e-7));
  m.curves.back().name = "";
  return m;
}

TEST(ModelJson, WriteThenReadIsBitExact) {
  const Model original = mixed_model();
  ASSERT_FALSE(original.validate()) << *original.validate();
  const std::string path = (temp_dir() / "round_trip.json").string();
  write_model(path, original);
  const Model back = read_model_json(path);
  EXPECT_EQ(back.units, original.units);
  ASSERT_EQ(back.surfaces.size(), original.surfaces.size());
  ASSERT_EQ(back.curves.size(), original.curves.size());
  for (std::size_t i = 0; i < original.surfaces.size(); ++i) {
    EXPECT_TRUE(same_surface(back.surfaces[i], original.surfaces[i])) << "surface " << i;
  }
  for (std::size_t i = 0; i < original.curves.size(); ++i) {
    EXPECT_TRUE(same_curve(back.curves[i], original.curves[i])) << "curve " << i;
  }
  // The text is also valid JSON to an independent parser, with the contract's nesting.
  const json document = json::parse(model_to_json(original));
  EXPECT_EQ(document["nurbsreg_model"], 1);
  EXPECT_EQ(document["surfaces"][0]["control_points"].size(), 7u);
  EXPECT_EQ(document["surfaces"][0]["control_points"][0].size(), 6u);
  EXPECT_EQ(document["surfaces"][0]["weights"][6].size(), 6u);
  EXPECT_FALSE(document["surfaces"][1].contains("weights"));
  EXPECT_EQ(document["curves"][1]["control_points"][0].size(), 2u);  // 2-D curve
  EXPECT_EQ(document["surfaces"][4]["name"], original.surfaces[4].name);
}

TEST(ModelJson, WriteRefusesAnInvalidModelAndLeavesNoFile) {
  Model m = mixed_model();
  m.surfaces[0].weights[3] = std::numeric_limits<double>::quiet_NaN();
  const auto path = temp_dir() / "invalid.json";
  std::filesystem::remove(path);
  EXPECT_THROW(write_model(path.string(), m), OutputError);
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(ModelJson, AcceptsTheContractsLatitude) {
  // Unknown keys ignored, null weights = non-rational, degree 3.0 is an integer, unclamped and
  // unnormalised knots, curves without surfaces, 3-D curve points.
  const std::string text = R"({"nurbsreg_model": 1.0, "units": "inch", "comment": "x",
    "curves": [{"name": "c", "degree": 2.0, "knots": [-3, -2, -1, 0, 1, 2], "weights": null,
                "control_points": [[0, 0, 1], [1, 1, 1], [2, 0, 1]], "color": "red"}]})";
  const Model m = parse_model(text, "m.json");
  ASSERT_EQ(m.curves.size(), 1u);
  EXPECT_TRUE(m.surfaces.empty());
  EXPECT_EQ(m.units, "inch");
  EXPECT_EQ(m.curves[0].degree, 2);
  EXPECT_EQ(m.curves[0].dimension, 3);
  EXPECT_FALSE(m.curves[0].is_rational());
  EXPECT_EQ(m.curves[0].domain().lo, -1.0);
  EXPECT_EQ(m.curves[0].domain().hi, 0.0);
}

// A valid one-surface document with one field's JSON text replaced ("" removes the field).
// Built as text so that values no JSON library accepts (1e999) reach the reader under test.
std::string surface_with(const std::string& key, const std::string& value) {
  const std::pair<const char*, const char*> fields[] = {
      {"name", R"("hood")"},
      {"degree", "[2, 1]"},
      {"knots_u", "[0, 0, 0, 0.5, 1, 1, 1]"},
      {"knots_v", "[0, 0, 1, 1]"},
      {"control_points",
       "[[[0,0,0],[0,1,0]], [[1,0,0],[1,1,0]], [[2,0,0],[2,1,0]], [[3,0,0],[3,1,0]]]"},
      {"weights", "[[1,1],[1,2],[1,1],[1,1]]"}};
  std::string entity;
  for (const auto& [name, text] : fields) {
    const std::string v = name == key ? value : std::string(text);
    if (v.empty()) continue;
    entity += (entity.empty() ? "" : ", ") + std::string("\"") + name + "\": " + v;
  }
  return R"({"nurbsreg_model": 1, "surfaces": [{)" + entity + "}]}";
}

struct ErrorCase {
  const char* what;
  std::string text;
  const char* expected;  // a substring of the message
};

class ModelJsonErrors : public ::testing::TestWithParam<ErrorCase> {};

TEST_P(ModelJsonErrors, NameTheFileEntityAndField) {
  const ErrorCase& c = GetParam();
  const std::string message = parse_error(c.text);
  ASSERT_FALSE(message.empty()) << c.what << ": accepted";
  EXPECT_EQ(message.rfind("m.json: ", 0), 0u) << message;
  EXPECT_NE(message.find(c.expected), std::string::npos) << c.what << "\n  got: " << message;
}

const std::string kCurveHead = R"({"nurbsreg_model": 1, "curves": [{"name": "arc", "degree": 2, )";

std::vector<ErrorCase> error_cases() {
  return {
      ErrorCase{"syntax", "{\"nurbsreg_model\": 1,\n  \"surfaces\": [,]}",
                "line 2, column 16: invalid JSON"},
      ErrorCase{"NaN literal", "{\"nurbsreg_model\": 1, \"curves\": [NaN]}",
                "line 1, column 34: invalid JSON"},
      ErrorCase{"empty file", "", "line 1, column 1: invalid JSON"},
      ErrorCase{"not an object", "[1, 2]", "expected a JSON object"},
      ErrorCase{"no version", R"({"surfaces": []})",
                "nurbsreg_model: missing: not a nurbsreg model"},
      ErrorCase{"future version", R"({"nurbsreg_model": 2})", "unsupported format version 2"},
      ErrorCase{"empty model", R"({"nurbsreg_model": 1, "surfaces": []})",
                "model: has no surfaces and no curves"},
      ErrorCase{"units", R"({"nurbsreg_model": 1, "units": 5})",
                "units: expected a non-empty string"},
      ErrorCase{"surfaces not array", R"({"nurbsreg_model": 1, "surfaces": {}})",
                "surfaces: expected an array"},
      ErrorCase{"surface not object", R"({"nurbsreg_model": 1, "surfaces": [3]})",
                "surface 0: expected an object"},
      ErrorCase{"name", surface_with("name", "7"), "surface 0: name: expected a string"},
      ErrorCase{"degree missing", surface_with("degree", ""),
                "surface 0 \"hood\": degree: missing (required)"},
      ErrorCase{"degree scalar", surface_with("degree", "3"),
                "surface 0 \"hood\": degree: expected an array"},
      ErrorCase{"degree arity", surface_with("degree", "[3]"),
                "degree: expected [degree_u, degree_v]"},
      ErrorCase{"degree fraction", surface_with("degree", "[2.5, 1]"),
                "degree[0]: expected an integer, got the number 2.5"},
      ErrorCase{"degree string", surface_with("degree", "[2, \"1\"]"),
                "degree[1]: expected an integer, got a string (\"1\")"},
      ErrorCase{"degree too high", surface_with("degree", "[13, 1]"),
                "degree: must be between 1 and 12 (got [13, 1])"},
      ErrorCase{"degree zero", surface_with("degree", "[2, 0]"),
                "degree: must be between 1 and 12"},
      ErrorCase{"knots too short", surface_with("knots_v", "[0, 1, 1]"),
                "surface 0 \"hood\": knots_v: has 3 values; degree 1 needs at least 4"},
      ErrorCase{"knots decreasing", surface_with("knots_u", "[0, 0, 0, 0.7, 0.5, 1, 1]"),
                "surface 0 \"hood\": knots_u: decreasing at index 4"},
      ErrorCase{"knot not number", surface_with("knots_u", "[0, 0, 0, \"a\", 1, 1, 1]"),
                "knots_u[3]: expected a number"},
      ErrorCase{"interior multiplicity", surface_with("knots_v", "[0, 0, 0.5, 0.5, 1, 1]"),
                "knots_v: interior knot 0.5 has multiplicity 2"},
      ErrorCase{"empty domain", surface_with("knots_v", "[0, 1, 1, 1]"),
                "knots_v: empty parameter domain"},
      ErrorCase{"rows", surface_with("control_points", "[[[0,0,0],[0,1,0]]]"),
                "control_points: expected 4 rows of 2"},
      ErrorCase{
          "ragged",
          surface_with("control_points",
                       "[[[0,0,0],[0,1,0]], [[1,0,0]], [[2,0,0],[2,1,0]], [[3,0,0],[3,1,0]]]"),
          "control_points[1]: expected 2 points (count_v), got 1"},
      ErrorCase{"2-D surface point",
                surface_with(
                    "control_points",
                    "[[[0,0,0],[0,1,0]], [[1,0,0],[1,1]], [[2,0,0],[2,1,0]], [[3,0,0],[3,1,0]]]"),
                "control_points[1][1]: expected 3 numbers [x, y, z], got 2"},
      ErrorCase{
          "coordinate string",
          surface_with(
              "control_points",
              "[[[0,0,0],[0,1,0]], [[1,0,0],[1,1,0]], [[2,0,0],[2,\"x\",0]], [[3,0,0],[3,1,0]]]"),
          "control_points[2][1][1]: expected a number"},
      ErrorCase{
          "coordinate overflow",
          surface_with(
              "control_points",
              "[[[0,0,0],[0,1,0]], [[1,0,0],[1,1,0]], [[2,0,0],[2,1,0]], [[3,0,1e999],[3,1,0]]]"),
          "invalid JSON: number overflow parsing '1e999'"},
      ErrorCase{"weight zero", surface_with("weights", "[[1,1],[1,0],[1,1],[1,1]]"),
                "surface 0 \"hood\": weights[1][1]: must be a finite number > 0 (got 0)"},
      ErrorCase{"weight negative", surface_with("weights", "[[1,1],[1,1],[1,1],[-1,1]]"),
                "weights[3][0]: must be a finite number > 0 (got -1)"},
      ErrorCase{"weights rows", surface_with("weights", "[1,1,1,1,1,1,1,1]"),
                "weights: expected 4 rows"},
      ErrorCase{"weights row length", surface_with("weights", "[[1,1],[1,1,1],[1,1],[1,1]]"),
                "weights[1]: expected 2 values (count_v), got 3"},
      ErrorCase{
          "curve degree",
          kCurveHead + R"("knots": [0,0,1,1], "control_points": [[0,0],[1,1]], "degree": "two"}]})",
          "curve 0 \"arc\": degree: expected an integer"},
      ErrorCase{"curve count",
                kCurveHead + R"("knots": [0,0,0,1,1,1], "control_points": [[0,0],[1,1]]}]})",
                "curve 0 \"arc\": control_points: expected 3 points (len(knots) - degree - 1 = 6 "
                "- 2 - 1), got 2"},
      ErrorCase{
          "curve mixed dimension",
          kCurveHead + R"("knots": [0,0,0,1,1,1], "control_points": [[0,0],[1,1,0],[2,0]]}]})",
          "control_points[1]: has 3 coordinates but control_points[0] has 2"},
      ErrorCase{"curve 1-D point",
                kCurveHead + R"("knots": [0,0,0,1,1,1], "control_points": [[0],[1],[2]]}]})",
                "control_points[0]: expected 2 or 3 numbers"},
      ErrorCase{
          "curve weights count",
          kCurveHead +
              R"("knots": [0,0,0,1,1,1], "control_points": [[0,0],[1,1],[2,0]], "weights": [1, 1]}]})",
          "curve 0 \"arc\": weights: expected 3 values (one per control point), got 2"},
      ErrorCase{
          "curve weight negative",
          kCurveHead +
              R"("knots": [0,0,0,1,1,1], "control_points": [[0,0],[1,1],[2,0]], "weights": [1, -0.5, 1]}]})",
          "curve 0 \"arc\": weights[1]: must be a finite number > 0 (got -0.5)"},
      ErrorCase{"second curve", R"({"nurbsreg_model": 1, "curves": [
            {"degree": 1, "knots": [0,0,1,1], "control_points": [[0,0],[1,1]]},
            {"degree": 1, "knots": [0,0,1,1], "control_points": [[0,0],[1,1]], "weights": [1, 0]}]})",
                "curve 1: weights[1]"}};
}

INSTANTIATE_TEST_SUITE_P(Table, ModelJsonErrors, ::testing::ValuesIn(error_cases()),
                         [](const ::testing::TestParamInfo<ErrorCase>& info) {
                           std::string name = info.param.what;
                           for (char& ch : name) {
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           }
                           return name;
                         });

// Counts implied by long knot vectors must not be trusted before the control points confirm
// them: 20,002 x 20,002 placeholder points would be 9.6 GB.
TEST(ModelJson, LongKnotVectorsWithFewPointsFailFastWithoutHugeAllocation) {
  std::string knots = "[0, 0, 0";
  for (int k = 0; k < 20000; ++k)
    knots += ", " + std::to_string(k);
  knots += ", 20000, 20000, 20000]";
  std::string text = surface_with("knots_u", knots);
  const std::string key = R"("knots_v": [0, 0, 1, 1])";
  text.replace(text.find(key), key.size(), "\"knots_v\": " + knots);
  text.replace(text.find(R"("degree": [2, 1])"), 16, R"("degree": [3, 3])");
  EXPECT_NE(
      parse_error(text).find("surface 0 \"hood\": control_points: expected 20002 rows of 20002"),
      std::string::npos)
      << parse_error(text);
}

TEST(ModelJson, UnreadableFilesAreInputErrors) {
  const auto dir = temp_dir();
  try {
    read_model_json((dir / "does_not_exist.json").string());
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("does_not_exist.json: cannot open"), std::string::npos)
        << e.what();
  }
  try {
    read_model_json(dir.string());
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("is a directory"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace nurbsreg::io
