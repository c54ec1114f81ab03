// The projector's fast paths checked against independent references on examples/folded.json (a
// hairpin: two layers 1 mm apart, so every point near it has two near-equal local minima):
//  - warm hints that point to the WRONG layer (the mirror foot u -> 1 - u, a genuine local
//    minimum of the distance) and random hints still give the global closest point: equal to the
//    cold answer and never above a dense sampling of the surface;
//  - the normal taken from the Bézier patch at the foot equals engine::surface_normal;
//  - PreparedModel::locate_patch finds the patch whose parameter box holds (u, v).
#include <gtest/gtest.h>

#include <random>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "support/example_surface.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::uniform;

// An independent reference: the closest of a dense parameter grid (an upper bound on the true
// minimum), refined by a 20 x 20 sub-grid around each of the 4 best grid samples.
double sampled_distance(const NurbsSurface& s, const std::vector<Vec3>& samples, int nu, int nv,
                        const Vec3& p) {
  std::vector<std::pair<double, int>> order;
  for (int k = 0; k < static_cast<int>(samples.size()); ++k)
    order.emplace_back((samples[k] - p).squaredNorm(), k);
  std::partial_sort(order.begin(), order.begin() + 4, order.end());
  double best = order[0].first;
  for (int c = 0; c < 4; ++c) {
    const int i = order[c].second / (nv + 1), j = order[c].second % (nv + 1);
    for (int a = -20; a <= 20; ++a) {
      for (int b = -20; b <= 20; ++b) {
        const double x = std::clamp((i + a / 20.0) / nu, 0.0, 1.0);
        const double y = std::clamp((j + b / 20.0) / nv, 0.0, 1.0);
        const Vec3 q = s.evaluate(s.domain_u().to_parent(x), s.domain_v().to_parent(y));
        best = std::min(best, (q - p).squaredNorm());
      }
    }
  }
  return std::sqrt(best);
}

class FoldedProjection : public ::testing::Test {
 protected:
  FoldedProjection() {
    Model m;
    m.surfaces.push_back(test::read_example_surface("folded.json"));
    prepared_ = std::make_unique<PreparedModel>(m);
    const NurbsSurface& s = prepared_->model().surfaces[0];
    // Points near both layers (within +-0.8 mm of one: the other is ~1 mm away), between them,
    // and around the fold.
    std::mt19937_64 rng(42);
    for (const SurfaceSample& x : sample_surfaces(prepared_->model(), 300, 9))
      points_.push_back(x.point + uniform(rng, -0.8, 0.8) * x.normal);
    for (int k = 0; k < 60; ++k) {
      const double u = uniform(rng, 0.9, 1.0), v = uniform(rng, 0.0, 1.0);
      points_.push_back(s.evaluate(u, v) + Vec3(uniform(rng, -1, 2), 0, uniform(rng, -1, 1)));
    }
    for (int i = 0; i <= kNu; ++i) {
      for (int j = 0; j <= kNv; ++j)
        samples_.push_back(s.evaluate(s.domain_u().to_parent(double(i) / kNu),
                                      s.domain_v().to_parent(double(j) / kNv)));
    }
  }
  static constexpr int kNu = 300, kNv = 60;
  std::unique_ptr<PreparedModel> prepared_;
  std::vector<Vec3> points_;
  std::vector<Vec3> samples_;
};

TEST_F(FoldedProjection, WrongLayerAndRandomHintsStillGiveTheGlobalFoot) {
  const NurbsSurface& s = prepared_->model().surfaces[0];
  Projector projector(*prepared_);
  ProjectionResults cold;
  projector.project(PointView::of(points_), {}, cold);
  std::mt19937_64 rng(8);
  std::vector<ProjectionHint> mirror(points_.size()), random(points_.size());
  int other_layer_minima = 0;
  for (std::size_t i = 0; i < points_.size(); ++i) {
    ASSERT_EQ(cold.status[i], ProjectionStatus::ok);
    // The mirrored parameter lies on the other layer; Newton from it converges to that layer's
    // own local minimum, a real trap for a warm start.
    mirror[i] = {0, 1.0 - cold.u[i], cold.v[i]};
    random[i] = {0, uniform(rng, -0.2, 1.2), uniform(rng, -0.2, 1.2)};
    const Vec3 trap = s.evaluate(1.0 - cold.u[i], cold.v[i]);
    if ((trap - points_[i]).norm() > cold.distance[i] + 0.1) ++other_layer_minima;
  }
  EXPECT_GT(other_layer_minima, 200);  // the mirror hints are mostly far from the answer
  ProjectionResults from_mirror, from_random;
  projector.project(PointView::of(points_), {}, from_mirror, mirror);
  projector.project(PointView::of(points_), {}, from_random, random);
  for (std::size_t i = 0; i < points_.size(); ++i) {
    const double reference = sampled_distance(s, samples_, kNu, kNv, points_[i]);
    // Exact answers are never above the sampled bound, and not far below it: the sub-grid
    // spacing is ~0.02 mm along u and 0.033 mm along v, so some sample lies within arc length
    // h = 0.04 mm of the true foot, and on a surface of curvature radius >= R = 0.4 mm (the fold)
    // reference^2 <= distance^2 + h^2 (1 + distance / R).
    const double h = 0.04, radius = 0.4;
    const double d = cold.distance[i];
    EXPECT_LE(d, reference + 1e-9) << i;
    EXPECT_GE(d * d + h * h * (1.0 + d / radius), reference * reference) << i;
    EXPECT_NEAR(from_mirror.distance[i], cold.distance[i], 1e-9) << i;
    EXPECT_NEAR(from_random.distance[i], cold.distance[i], 1e-9) << i;
    EXPECT_LT((s.evaluate(from_mirror.u[i], from_mirror.v[i]) - from_mirror.foot[i]).norm(), 1e-9);
  }
}

TEST_F(FoldedProjection, NormalFromThePatchEqualsTheSurfaceNormal) {
  const NurbsSurface& s = prepared_->model().surfaces[0];
  Projector projector(*prepared_);
  ProjectionResults results;
  projector.project(PointView::of(points_), {}, results);
  for (std::size_t i = 0; i < points_.size(); ++i) {
    const Vec3 reference = surface_normal(s, results.u[i], results.v[i]);
    EXPECT_LT((results.normal[i] - reference).norm(), 1e-9) << i;
    const double side = (points_[i] - results.foot[i]).dot(reference);
    if (std::abs(side) > 1e-9) {
      EXPECT_EQ(results.signed_distance[i] > 0, side > 0) << i;
    }
  }
}

TEST(PreparedModelLocate, FindsThePatchHoldingTheParameters) {
  Model m;
  m.surfaces.push_back(test::random_surface(3, 3, 2, 9, 6, true));
  m.surfaces.push_back(test::random_surface(4, 2, 3, 5, 11, false));
  const PreparedModel prepared(m);
  std::mt19937_64 rng(1);
  for (int surface = 0; surface < 2; ++surface) {
    const NurbsSurface& s = prepared.model().surfaces[surface];
    for (int k = 0; k < 500; ++k) {
      // Random parameters, plus exact breakpoints and the domain ends.
      double u = s.domain_u().to_parent(uniform(rng, 0, 1));
      double v = s.domain_v().to_parent(uniform(rng, 0, 1));
      if (k % 5 == 0) u = s.knots_u[static_cast<std::size_t>(rng() % s.knots_u.size())];
      if (k % 7 == 0) v = s.knots_v[static_cast<std::size_t>(rng() % s.knots_v.size())];
      const std::int64_t patch = prepared.locate_patch(surface, u, v);
      ASSERT_GE(patch, 0);
      const BezierPatch& bp = prepared.patch(static_cast<std::size_t>(patch)).patch;
      EXPECT_EQ(prepared.patch_surface(static_cast<std::size_t>(patch)), surface);
      EXPECT_LE(bp.param_u.lo, u);
      EXPECT_GE(bp.param_u.hi, u);
      EXPECT_LE(bp.param_v.lo, v);
      EXPECT_GE(bp.param_v.hi, v);
    }
  }
}

}  // namespace
}  // namespace nurbsreg::engine
