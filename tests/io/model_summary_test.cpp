// Model summaries (`info`): patch counts against the knot vectors' distinct spans (counted here,
// independently of the decomposition), boxes against exact shapes (sphere, circle: the Bézier
// control boxes are exact) and against sampled points for random rational surfaces.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <random>
#include <set>

#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/io/cad_import.hpp"
#include "nurbsreg/io/model_summary.hpp"
#include "support/random_entities.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::io {
namespace {

using engine::Vec3;

// Non-empty knot spans inside the domain [knots[p], knots[n]].
std::size_t spans(const std::vector<double>& knots, int degree) {
  const std::size_t n = knots.size() - degree - 1;
  std::set<double> distinct(knots.begin() + degree, knots.begin() + n + 1);
  return distinct.size() - 1;
}

TEST(ModelSummary, ExactShapesHaveExactBoxes) {
  engine::Model m;
  m.units = "mm";
  m.surfaces.push_back(engine::make_sphere(Vec3(1, -2, 3), 2.5));
  m.surfaces.push_back(engine::make_torus(Vec3(0, 0, -10), 3, 1));
  m.curves.push_back(engine::make_circle(Vec3(0, 0, 7), 4));
  const ModelSummary s = summarize_model(m);
  ASSERT_EQ(s.surfaces.size(), 2u);
  const double tol = 1e-12;
  EXPECT_LT((s.surfaces[0].box.lo - Vec3(1 - 2.5, -2 - 2.5, 3 - 2.5)).norm(), tol);
  EXPECT_LT((s.surfaces[0].box.hi - Vec3(1 + 2.5, -2 + 2.5, 3 + 2.5)).norm(), tol);
  // Torus: |x|, |y| <= R + r, |z - c| <= r.
  EXPECT_LT((s.surfaces[1].box.lo - Vec3(-4, -4, -11)).norm(), tol);
  EXPECT_LT((s.surfaces[1].box.hi - Vec3(4, 4, -9)).norm(), tol);
  EXPECT_LT((s.curves[0].box.lo - Vec3(-4, -4, 7)).norm(), tol);
  EXPECT_LT((s.curves[0].box.hi - Vec3(4, 4, 7)).norm(), tol);
  EXPECT_LT((s.box.lo - Vec3(-4, -4.5, -11)).norm(), tol);
  EXPECT_LT((s.box.hi - Vec3(4, 4, 7)).norm(), tol);
  for (std::size_t k = 0; k < 2; ++k) {
    const auto& surface = m.surfaces[k];
    EXPECT_EQ(s.surfaces[k].bezier_pieces,
              spans(surface.knots_u, surface.degree_u) * spans(surface.knots_v, surface.degree_v));
  }
  EXPECT_EQ(s.curves[0].bezier_pieces, 4u);  // four quarter arcs
  EXPECT_EQ(s.bezier_patches, s.surfaces[0].bezier_pieces + s.surfaces[1].bezier_pieces);
  EXPECT_TRUE(s.surfaces[0].rational);
}

TEST(ModelSummary, BoxesContainTheSurfaceAndBeatTheControlNet) {
  engine::Model m;
  for (int k = 0; k < 6; ++k) {
    m.surfaces.push_back(
        test::random_surface(300 + k, 1 + k % 4, 2 + k % 3, 8 + k, 7, k % 2 == 0, k % 3 != 0));
  }
  const ModelSummary s = summarize_model(m);
  std::mt19937_64 rng(17);
  for (std::size_t k = 0; k < m.surfaces.size(); ++k) {
    const auto& surface = m.surfaces[k];
    const auto& e = s.surfaces[k];
    EXPECT_EQ(e.bezier_pieces,
              spans(surface.knots_u, surface.degree_u) * spans(surface.knots_v, surface.degree_v));
    engine::Aabb net;
    for (const Vec3& p : surface.control_points)
      net.extend(p);
    EXPECT_TRUE((e.box.lo.array() >= net.lo.array() - 1e-12).all() &&
                (e.box.hi.array() <= net.hi.array() + 1e-12).all());
    for (int t = 0; t < 2000; ++t) {
      const Vec3 p = surface.evaluate(e.domain_u.to_parent(test::uniform(rng, 0, 1)),
                                      e.domain_v.to_parent(test::uniform(rng, 0, 1)));
      ASSERT_TRUE((p.array() >= e.box.lo.array() - 1e-12).all() &&
                  (p.array() <= e.box.hi.array() + 1e-12).all())
          << "surface " << k << " point " << p.transpose();
    }
  }
}

TEST(ModelSummary, TextAndJsonNameEverything) {
  engine::Model m;
  m.units = "m";
  m.surfaces.push_back(engine::make_sphere(Vec3(0, 0, 0), 1));
  m.surfaces.back().name = "ball";
  m.curves.push_back(test::random_curve(5, 3, 7, false, true, 2));
  m.curves.back().name = "";
  const ModelSummary s = summarize_model(m);
  const std::string text = format_model_summary(s, "ball.json");
  EXPECT_NE(text.find("model: ball.json (units m)\n"), std::string::npos) << text;
  EXPECT_NE(text.find("surfaces: 1 (1 rational), Bézier patches: 8\n"), std::string::npos) << text;
  EXPECT_NE(text.find("  surface 0 \"ball\": degree (2, 2), 5 x 9 control points, rational, 8 "
                      "Bézier patches, u [0, 1], v [0, 1]\n"),
            std::string::npos)
      << text;
  const std::size_t pieces = spans(m.curves[0].knots, 3);
  EXPECT_NE(text.find("  curve 0: degree 3, 7 control points, polynomial, " +
                      std::to_string(pieces) + " Bézier pieces"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("bounding box: (-1, -1, -1) .. (1, 1, 1)"), std::string::npos) << text;
  const nlohmann::json j = nlohmann::json::parse(model_summary_to_json(s));
  EXPECT_EQ(j["units"], "m");
  EXPECT_EQ(j["bezier_patches"], 8);
  EXPECT_EQ(j["surfaces"][0]["degree"], nlohmann::json({2, 2}));
  EXPECT_EQ(j["surfaces"][0]["control_points"], nlohmann::json({5, 9}));
  EXPECT_EQ(j["curves"][0]["bezier_pieces"], pieces);
  EXPECT_EQ(j["bounding_box"]["max"][2], 1.0);
}

// A CAD model: every face listed with its trimming and orientation, skipped faces with reasons.
TEST(ModelSummary, ListsTrimmingOrientationAndSkippedFaces) {
  engine::Model m = read_cad_file(nurbsreg::test::shared_dir() + "/data/real/occt/screw.step");
  m.skipped_faces.push_back({10, "a reason"});  // the file has none: add one to see it listed
  const ModelSummary s = summarize_model(m);
  ASSERT_EQ(s.surfaces.size(), m.surfaces.size());
  std::size_t trimmed = 0, reversed = 0;
  for (std::size_t k = 0; k < m.surfaces.size(); ++k) {
    std::size_t curves = 0;
    for (const engine::TrimLoop& loop : m.surfaces[k].trim_loops)
      curves += loop.curves.size();
    EXPECT_EQ(s.surfaces[k].trim_loops, m.surfaces[k].trim_loops.size());
    EXPECT_EQ(s.surfaces[k].trim_curves, curves);
    EXPECT_EQ(s.surfaces[k].reversed, m.surfaces[k].reversed);
    trimmed += m.surfaces[k].is_trimmed() ? 1 : 0;
    reversed += m.surfaces[k].reversed ? 1 : 0;
  }
  EXPECT_EQ(s.trimmed_surfaces, trimmed);
  EXPECT_GT(trimmed, 0u);
  const std::string text = format_model_summary(s, "screw.step");
  EXPECT_NE(text.find(std::to_string(trimmed) + " trimmed)"), std::string::npos) << text;
  EXPECT_NE(text.find("surface 0 \"face 0\""), std::string::npos) << text;
  EXPECT_NE(text.find("trimmed (" + std::to_string(s.surfaces[0].trim_loops) + " loops, " +
                      std::to_string(s.surfaces[0].trim_curves) + " curves)"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("skipped face 10: a reason"), std::string::npos) << text;
  const auto j = nlohmann::json::parse(model_summary_to_json(s));
  EXPECT_EQ(j["trimmed_surfaces"], trimmed);
  EXPECT_EQ(j["surfaces"][0]["trimmed"], true);
  EXPECT_EQ(j["surfaces"][0]["trim_curves"], s.surfaces[0].trim_curves);
  std::size_t reversed_json = 0;
  for (const auto& e : j["surfaces"])
    reversed_json += e["reversed"].get<bool>() ? 1 : 0;
  EXPECT_EQ(reversed_json, reversed);
  ASSERT_EQ(j["skipped_faces"].size(), 1u);
  EXPECT_EQ(j["skipped_faces"][0]["face"], 10);
  EXPECT_EQ(j["skipped_faces"][0]["reason"], "a reason");
}

}  // namespace
}  // namespace nurbsreg::io
