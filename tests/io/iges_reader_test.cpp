// IGES import on real CAD files. Oracles: the per-file counts in shared/data/real/SOURCES.md;
// the same parts exported as STEP (wigley, goteborg, the IEA blade): points sampled on each IGES
// surface must lie on the surfaces read from the STEP twin, two unrelated formats and readers;
// and small synthetic files for the layout rules (first index fastest, type-124 transforms).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/iges_reader.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/io/step_reader.hpp"
#include "support/io_surface_distance.hpp"

namespace nurbsreg::io {
namespace {

using engine::NurbsSurface;
using engine::Vec3;

std::string data_path(const std::string& relative) {
  return std::string(NURBSREG_SHARED_DIR) + "/data/real/" + relative;
}

std::vector<std::array<int, 4>> shapes_of(const engine::Model& m) {
  std::vector<std::array<int, 4>> shapes;
  for (const auto& s : m.surfaces)
    shapes.push_back({s.degree_u, s.degree_v, s.count_u, s.count_v});
  std::sort(shapes.begin(), shapes.end());
  return shapes;
}

struct FileCase {
  const char* file;
  std::size_t surfaces;
  std::vector<std::array<int, 4>> shapes;  // sorted; empty = not checked
  const char* units;
};

class IgesFiles : public ::testing::TestWithParam<FileCase> {};

TEST_P(IgesFiles, MatchSources) {
  const FileCase& c = GetParam();
  IgesImportReport report;
  const engine::Model model = read_iges(data_path(c.file), &report);
  EXPECT_EQ(model.surfaces.size(), c.surfaces);
  EXPECT_EQ(report.bspline_surfaces, c.surfaces);
  EXPECT_EQ(model.units, c.units);
  if (!c.shapes.empty()) {
    EXPECT_EQ(shapes_of(model), c.shapes);
  }
  EXPECT_FALSE(model.validate());
}

INSTANTIATE_TEST_SUITE_P(
    Real, IgesFiles,
    ::testing::Values(
        FileCase{"dealii/wigley.iges", 1, {{3, 4, 4, 11}}, "m"},
        FileCase{"dealii/goteborg.iges", 3, {{3, 3, 16, 10}, {3, 3, 19, 14}, {3, 5, 4, 81}}, "m"},
        FileCase{"dealii/DTMB-5415_bulbous_bow.iges", 1, {{3, 3, 19, 14}}, "m"},
        FileCase{
            "dealii/wing.iges", 4, {{1, 1, 2, 2}, {1, 1, 2, 2}, {3, 1, 69, 2}, {3, 1, 69, 2}}, "m"},
        FileCase{
            "iea-15mw/IEA_15MW_CFD.igs", 3, {{3, 3, 4, 17}, {3, 8, 17, 204}, {3, 8, 17, 204}}, "m"},
        FileCase{"bladex/upper.iges", 1, {{3, 2, 526, 13}}, "mm"},
        FileCase{"bladex/lower.iges", 1, {{3, 2, 526, 13}}, "mm"},
        FileCase{"occt/bearing.iges", 213, {}, "mm"}, FileCase{"occt/hammer.iges", 45, {}, "mm"}),
    [](const ::testing::TestParamInfo<FileCase>& info) {
      std::string name = info.param.file;
      name = name.substr(name.find('/') + 1);
      for (char& ch : name) {
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      }
      return name;
    });

struct TwinCase {
  const char* iges;
  const char* step;
};

class IgesStepTwins : public ::testing::TestWithParam<TwinCase> {};

TEST_P(IgesStepTwins, SurfacesCoincide) {
  const engine::Model iges = read_iges(data_path(GetParam().iges));
  const engine::Model step = read_step(data_path(GetParam().step));
  ASSERT_EQ(iges.surfaces.size(), step.surfaces.size());
  std::vector<test::SampledSurface> targets;
  engine::Aabb box;
  for (const auto& s : step.surfaces) {
    targets.push_back(test::sample(s));
    for (const Vec3& p : s.control_points)
      box.extend(p);
  }
  double worst = 0.0;
  for (const NurbsSurface& s : iges.surfaces) {
    const auto du = s.domain_u();
    const auto dv = s.domain_v();
    for (int i = 0; i <= 6; ++i) {
      for (int j = 0; j <= 6; ++j) {
        const Vec3 p = s.evaluate(du.to_parent(i / 6.0), dv.to_parent(j / 6.0));
        double nearest = std::numeric_limits<double>::infinity();
        for (const auto& t : targets)
          nearest = std::min(nearest, test::distance_to(t, p));
        worst = std::max(worst, nearest);
      }
    }
  }
  EXPECT_LT(worst, 1e-7 * box.diagonal()) << "diagonal " << box.diagonal();
}

INSTANTIATE_TEST_SUITE_P(Real, IgesStepTwins,
                         ::testing::Values(TwinCase{"dealii/wigley.iges", "dealii/wigley.step"},
                                           TwinCase{"dealii/goteborg.iges", "dealii/goteborg.step"},
                                           TwinCase{"iea-15mw/IEA_15MW_CFD.igs",
                                                    "iea-15mw/IEA_15MW_CFD.stp"}));

// A minimal fixed-format IGES file: entities given as (type, parameters after the type,
// transformation DE pointer), laid out in 80-column records as IGES 5.3 §2 prescribes.
struct SyntheticEntity {
  int type;
  std::string parameters;  // "a,b,c" (no type, no ';')
  int transformation = 0;
};

std::string record(const std::string& data, char section, int sequence) {
  char tail[16];
  std::snprintf(tail, sizeof(tail), "%c%7d", section, sequence);
  std::string line = data;
  line.resize(72, ' ');
  return line + tail + "\n";
}

std::string make_iges(const std::vector<SyntheticEntity>& entities, const std::string& global) {
  std::string out = record("synthetic", 'S', 1) + record(global, 'G', 1);
  std::string directory, parameters;
  int p_sequence = 1;
  for (std::size_t k = 0; k < entities.size(); ++k) {
    const int de = static_cast<int>(2 * k + 1);
    // Parameter records: columns 1-64 data (split at commas), 66-72 the DE pointer.
    std::vector<std::string> lines{""};
    std::string data = std::to_string(entities[k].type) + "," + entities[k].parameters + ";";
    std::size_t start = 0;
    while (start < data.size()) {
      std::size_t end = data.find_first_of(",;", start);
      const std::string token = data.substr(start, end - start + 1);
      if (lines.back().size() + token.size() > 64) lines.emplace_back();
      lines.back() += token;
      start = end + 1;
    }
    const int first = p_sequence;
    for (const std::string& l : lines) {
      char pointer[16];
      std::snprintf(pointer, sizeof(pointer), " %7d", de);
      std::string padded = l;
      padded.resize(64, ' ');
      parameters += record(padded + pointer, 'P', p_sequence++);
    }
    char a[80], b[80];
    std::snprintf(a, sizeof(a), "%8d%8d%8d%8d%8d%8d%8d%8d%8s", entities[k].type, first, 0, 0, 0, 0,
                  entities[k].transformation, 0, "00000000");
    std::snprintf(b, sizeof(b), "%8d%8d%8d%8d%8d%8s%8s%8s%8d", entities[k].type, 0, 0,
                  static_cast<int>(lines.size()), 0, "", "", "PATCH", 0);
    directory += record(a, 'D', de) + record(b, 'D', de + 1);
  }
  return out + directory + parameters + record("S      1G      1", 'T', 1);
}

// Bilinear patch, K1 = 2 (three points along u), K2 = 1: points (i, j, i * j) listed with the
// first index fastest, weights 1..6 in the same order.
std::string patch_parameters(bool polynomial, const std::string& first_weight = "1.") {
  std::string p = "2,1,1,1,0,0," + std::string(polynomial ? "1" : "0") + ",0,0,";
  p += "0.,0.,0.5,1.,1.,";  // knots_u: 3 points, degree 1
  p += "0.,0.,1.,1.,";      // knots_v
  p += first_weight + ",2.,3.,4.,5.,6.,";
  for (int j = 0; j <= 1; ++j) {
    for (int i = 0; i <= 2; ++i)
      p += std::to_string(i) + "," + std::to_string(j) + "," + std::to_string(i * j) + ",";
  }
  return p + "0.,1.,0.,1.";
}

const std::string kGlobal =
    ",,,13Hsynthetic.igs,,,32,38,6,308,15,,1.,2,2HMM,1,0.01,,1E-07,10.,,,11,0,;";

TEST(IgesReader, FirstIndexRunsAlongU) {
  IgesImportReport report;
  const engine::Model m =
      parse_iges(make_iges({{128, patch_parameters(false)}}, kGlobal), "s.igs", &report);
  ASSERT_EQ(m.surfaces.size(), 1u);
  const NurbsSurface& s = m.surfaces[0];
  EXPECT_EQ(m.units, "mm");
  EXPECT_EQ(s.name, "PATCH");
  EXPECT_EQ(s.count_u, 3);
  EXPECT_EQ(s.count_v, 2);
  EXPECT_EQ(s.point(2, 1), Vec3(2, 1, 2));
  EXPECT_EQ(s.point(1, 0), Vec3(1, 0, 0));
  EXPECT_EQ(s.weight(2, 0), 3.0);  // third value: i = 2, j = 0
  EXPECT_EQ(s.weight(0, 1), 4.0);
  EXPECT_LT((s.evaluate(1.0, 1.0) - Vec3(2, 1, 2)).norm(), 1e-15);
  EXPECT_EQ(report.rational_surfaces, 1u);
  const engine::Model poly =
      parse_iges(make_iges({{128, patch_parameters(true)}}, kGlobal), "s.igs");
  EXPECT_FALSE(poly.surfaces[0].is_rational());
}

TEST(IgesReader, AppliesChainedTransformations) {
  // DE 1: the patch, transformed by DE 3 (rotate 90 degrees about z), which is itself followed
  // by DE 5 (translate by (10, 0, 0)): x' = T5(T3(x)).
  const std::string rotate = "0.,-1.,0.,0.,1.,0.,0.,0.,0.,0.,1.,0.";
  const std::string translate = "1.,0.,0.,10.,0.,1.,0.,0.,0.,0.,1.,0.";
  IgesImportReport report;
  const engine::Model m = parse_iges(
      make_iges({{128, patch_parameters(true), 3}, {124, rotate, 5}, {124, translate}}, kGlobal),
      "s.igs", &report);
  EXPECT_EQ(report.transformed, 1u);
  EXPECT_EQ(m.surfaces[0].point(2, 1), Vec3(10 - 1, 2, 2));
}

std::string iges_error(const std::string& text) {
  try {
    parse_iges(text, "bad.igs");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(IgesReader, ErrorsNameTheEntityAndField) {
  EXPECT_NE(iges_error("solid cube\n").find("bad.igs: line 1: not a fixed-format IGES file"),
            std::string::npos);
  EXPECT_NE(
      iges_error(make_iges({{128, patch_parameters(false, "0.")}}, kGlobal))
          .find("bad.igs: DE 1 (type 128): weights[0][0]: must be a finite number > 0 (got 0)"),
      std::string::npos)
      << iges_error(make_iges({{128, patch_parameters(false, "0.")}}, kGlobal));
  // Parameter data that stops right after the six weights.
  std::string truncated = patch_parameters(false);
  truncated = truncated.substr(0, truncated.find("6.,") + 2);
  EXPECT_NE(iges_error(make_iges({{128, truncated}}, kGlobal))
                .find("DE 1 (type 128): K1, K2: (2, 1) imply 42 parameters, the entity has 24 (the "
                      "parameter data ends early)"),
            std::string::npos)
      << iges_error(make_iges({{128, truncated}}, kGlobal));
  EXPECT_NE(iges_error(make_iges({{128, patch_parameters(true), 3}, {126, "1"}}, kGlobal))
                .find("transformation pointer DE 3 (type 126) is not type 124"),
            std::string::npos);
  EXPECT_NE(iges_error(make_iges({{126, "1,2"}}, kGlobal)).find("no B-spline surfaces (type 128)"),
            std::string::npos);
}

TEST(ModelFile, DispatchesOnExtension) {
  EXPECT_EQ(read_model_file(data_path("dealii/wigley.step")).surfaces.size(), 1u);
  EXPECT_EQ(read_model_file(data_path("dealii/wigley.iges")).surfaces.size(), 1u);
  EXPECT_EQ(read_model_file(data_path("iea-15mw/IEA_15MW_CFD.igs")).surfaces.size(), 3u);
  try {
    read_model_file(data_path("pcl/bunny.pcd"));
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown model format"), std::string::npos);
  }
}

}  // namespace
}  // namespace nurbsreg::io
