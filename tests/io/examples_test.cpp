// The committed example models (examples/*.json, written by examples/generate_examples.cpp)
// load through io::read_model_json and have the properties examples/README.md promises.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <tuple>

#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::io {
namespace {

using engine::Model;
using engine::NurbsSurface;
using engine::Vec3;

std::string example(const std::string& name) {
  return nurbsreg::test::examples_dir() + "/" + name;
}

Model load(const std::string& name) {
  const std::string path = example(name);
  EXPECT_LT(std::filesystem::file_size(path), 200u * 1024u) << name;
  Model m = read_model_json(path);
  EXPECT_EQ(m.units, "mm") << name;
  return m;
}

bool same_surface(const NurbsSurface& a, const NurbsSurface& b) {
  return a.degree_u == b.degree_u && a.degree_v == b.degree_v && a.knots_u == b.knots_u &&
         a.knots_v == b.knots_v && a.control_points == b.control_points && a.weights == b.weights;
}

TEST(Examples, PanelsHaveTheStatedPatchCountsAndHeights) {
  for (const auto& [file, count, patches] :
       {std::tuple{"panel.json", 10, 49}, std::tuple{"panel_1369.json", 40, 1369}}) {
    const Model m = load(file);
    ASSERT_EQ(m.surfaces.size(), 1u);
    const NurbsSurface& s = m.surfaces[0];
    EXPECT_EQ(s.degree_u, 3);
    EXPECT_EQ(s.degree_v, 3);
    EXPECT_EQ(s.count_u, count);
    EXPECT_EQ(s.count_v, count);
    EXPECT_FALSE(s.is_rational());
    EXPECT_EQ(static_cast<int>(engine::decompose(s).size()), patches) << file;
    // Non-uniform: the knot spans differ by more than a factor 2.
    double lo = 1.0;
    double hi = 0.0;
    for (int k = s.degree_u; k < s.count_u; ++k) {
      lo = std::min(lo, s.knots_u[k + 1] - s.knots_u[k]);
      hi = std::max(hi, s.knots_u[k + 1] - s.knots_u[k]);
    }
    EXPECT_GT(hi / lo, 2.0) << file;
    double z_lo = 1e9;
    double z_hi = -1e9;
    for (int i = 0; i <= 50; ++i) {
      for (int j = 0; j <= 50; ++j) {
        const Vec3 p = s.evaluate(i / 50.0, j / 50.0);
        z_lo = std::min(z_lo, p.z());
        z_hi = std::max(z_hi, p.z());
        EXPECT_GE(p.x(), -1.0);
        EXPECT_LE(p.x(), 104.0);
      }
    }
    EXPECT_GT(z_lo, 1.0) << file;
    EXPECT_LT(z_hi, 16.0) << file;
    EXPECT_GT(z_hi - z_lo, 8.0) << file;
  }
}

TEST(Examples, ExactShapesRoundTripExactly) {
  const Model sphere = load("sphere.json");
  ASSERT_EQ(sphere.surfaces.size(), 1u);
  EXPECT_TRUE(same_surface(sphere.surfaces[0], engine::make_sphere(Vec3(0, 0, 0), 25.0)));
  const Model torus = load("torus.json");
  ASSERT_EQ(torus.surfaces.size(), 1u);
  EXPECT_TRUE(same_surface(torus.surfaces[0], engine::make_torus(Vec3(0, 0, 0), 40.0, 10.0)));
}

TEST(Examples, FoldedSheetLayersAreAboutOneMillimetreApart) {
  const Model m = load("folded.json");
  ASSERT_EQ(m.surfaces.size(), 1u);
  const NurbsSurface& s = m.surfaces[0];
  // The sheet is mirror-symmetric about the fold (u <-> 1 - u): the point of the other layer
  // "below" S(u, v) is S(1 - u, v). Along the straight layers (u <= 0.35) the gap is 1 mm up to
  // the 1e-3 rounding of the control points; towards the fold it closes (S(0.5) is the fold).
  double gap_lo = 1e9;
  double gap_hi = 0.0;
  for (int i = 0; i <= 40; ++i) {
    const double u = 0.35 * i / 40.0;
    for (int j = 0; j <= 20; ++j) {
      const double v = j / 20.0;
      const double gap = (s.evaluate(u, v) - s.evaluate(1.0 - u, v)).norm();
      gap_lo = std::min(gap_lo, gap);
      gap_hi = std::max(gap_hi, gap);
    }
  }
  EXPECT_GT(gap_lo, 0.99);
  EXPECT_LT(gap_hi, 1.01);
  // The fold is at the far end (x ~ 60 mm).
  EXPECT_GT(s.evaluate(0.5, 0.5).x(), 58.0);
}

TEST(Examples, RationalPanelWeightsSpanFourDecades) {
  const Model m = load("rational_panel.json");
  ASSERT_EQ(m.surfaces.size(), 1u);
  const auto& w = m.surfaces[0].weights;
  ASSERT_FALSE(w.empty());
  EXPECT_EQ(*std::min_element(w.begin(), w.end()), 0.01);
  EXPECT_EQ(*std::max_element(w.begin(), w.end()), 100.0);
}

TEST(Examples, CurvesArePlanarTwistedAndCircular) {
  const Model m = load("curves.json");
  ASSERT_EQ(m.curves.size(), 3u);
  EXPECT_EQ(m.curves[0].dimension, 2);
  EXPECT_EQ(m.curves[1].dimension, 3);
  // Twisted: not planar (the control polygon spans three dimensions with a non-zero volume).
  const auto& p = m.curves[1].control_points;
  EXPECT_GT(std::abs((p[3] - p[0]).cross(p[6] - p[0]).dot(p[9] - p[0])), 100.0);
  const engine::NurbsCurve circle = engine::make_circle(Vec3(0, 0, 0), 30.0);
  EXPECT_EQ(m.curves[2].knots, circle.knots);
  EXPECT_EQ(m.curves[2].control_points, circle.control_points);
  EXPECT_EQ(m.curves[2].weights, circle.weights);
}

}  // namespace
}  // namespace nurbsreg::io
