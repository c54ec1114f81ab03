// Chained cold frames (engine::ProjectionOptions::chain_cold) on real trimmed CAD parts: a scan of
// tens of thousands of points near the faces (noise 0.5% of the trimmed diagonal, issue 26's
// benchmark) and as many anywhere in the part's box, projected with near lists and with a
// separate search per point. The separate searches are checked against an OpenCASCADE-only
// reference in cad_projection_test.cpp; here the chained answers must equal them (distances to
// the clipping's accuracy), while the lists prove most of the near answers: trimmed faces whose
// trim edges are items of the lists, rational patches (the hammer), faces meeting at edges.
#include <gtest/gtest.h>

#include <random>
#include <string>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::io {
namespace {

using engine::Vec3;

engine::ProjectionResults project(const engine::PreparedModel& model,
                                  const std::vector<Vec3>& points, bool chained,
                                  engine::ProjectionCounters* counters = nullptr) {
  engine::ProjectionOptions options;
  options.chain_cold = chained;
  engine::ProjectionResults results;
  engine::Projector(model).project(engine::PointView::of(points), options, results, {}, counters);
  return results;
}

class CadChainedProjection : public ::testing::TestWithParam<const char*> {};

TEST_P(CadChainedProjection, SameAnswersAsSeparateSearches) {
  const std::string path = nurbsreg::test::shared_dir() + "/data/real/" + GetParam();
  const engine::Model model = read_model_file(path);
  const engine::PreparedModel prepared(model);
  const engine::Aabb box = prepared.geometry_bounds().box;
  const double diagonal = box.diagonal();
  engine::SyntheticScanOptions scan;
  scan.points = 40000;
  scan.noise_sigma = 0.005 * diagonal;
  scan.seed = 4;
  std::vector<Vec3> near = engine::make_synthetic_scan(model, scan).points;
  std::mt19937_64 rng(8);
  std::vector<Vec3> mixed = near;
  mixed.resize(near.size() / 2);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  while (mixed.size() < near.size()) {
    const Vec3 f(unit(rng), unit(rng), unit(rng));
    mixed.push_back(box.lo + f.cwiseProduct(box.hi - box.lo));
  }
  const double tolerance = 1e-10 * diagonal;
  for (const auto* points : {&near, &mixed}) {
    const char* what = points == &near ? "near" : "mixed";
    engine::ProjectionCounters counters;
    const engine::ProjectionResults chained = project(prepared, *points, true, &counters);
    const engine::ProjectionResults separate = project(prepared, *points, false);
    std::size_t ties = 0;
    for (std::size_t i = 0; i < points->size(); ++i) {
      ASSERT_EQ(chained.status[i], separate.status[i]) << what << " point " << i;
      ASSERT_NEAR(chained.distance[i], separate.distance[i], tolerance)
          << what << " point " << i << " " << (*points)[i].transpose();
      ties += chained.entity[i] != separate.entity[i];
    }
    // Where the faces differ, both are at the same distance (a shared edge): rare.
    EXPECT_LT(ties, points->size() / 100) << what;
    if (points == &near) {
      EXPECT_GT(counters.listed, points->size() / 2) << what;
    }
    std::printf("%s %s: %.1f%% proven by near lists, %.1f%% made one, %zu entity ties\n",
                GetParam(), what, 100.0 * counters.listed / points->size(),
                100.0 * counters.lists_made / points->size(), ties);
  }
}

INSTANTIATE_TEST_SUITE_P(
    RealParts, CadChainedProjection, ::testing::Values("occt/bearing.iges", "occt/hammer.iges"),
    [](const auto& info) {
      return std::string(info.param).substr(5, std::string(info.param).find('.') - 5);
    });

}  // namespace
}  // namespace nurbsreg::io
