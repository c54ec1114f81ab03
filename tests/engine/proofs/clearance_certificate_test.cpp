// Clearance certificates (WarmCertificate::clearance_only, ProjectionOptions::certify_clearance):
// "everything but the foot's patch P is at least `clearance` from the anchor". A later query
// whose hint lies on P gets P's own exact minimum d (Newton, then P's clipping) and is proven
// when d + |q - anchor| <= clearance. Checked against cold projections of the same points on
// the two models where such a proof can go wrong:
//  - a hairpin (two layers 0.3 apart, in different patches): points moved towards the other
//    layer, where P's minimum still lies within the clearance but the other layer is nearer;
//    the test counts those cases, so that dropping the |q - anchor| term fails it;
//  - one patch with two local minima of the distance (a trough, points above its centre of
//    curvature): hints on the wrong slope, where Newton alone stops at the wrong local
//    minimum; the test counts those, so that skipping P's clipping fails it.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/engine/surface_projection.hpp"
#include "support/hard_surfaces.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::uniform;

// Points within +-0.25 of the model's surface (between the layers where they are 0.3 apart).
std::vector<Vec3> points_near(const PreparedModel& model, std::size_t count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Vec3> points;
  for (const SurfaceSample& x : sample_surfaces(model.model(), count, seed))
    points.push_back(x.point + uniform(rng, -0.25, 0.25) * x.normal);
  return points;
}

TEST(ClearanceCertificate, MovedPointsAreProvenOnlyWhereNothingElseCameNearer) {
  const PreparedModel model(test::model_of({test::hairpin(0.3)}));
  const double diagonal = model.bounds().diagonal();
  const std::vector<Vec3> anchors = points_near(model, 3000, 5);
  Projector projector(model);
  ProjectionOptions making;
  making.certify_clearance = true;
  making.certificate_radius = 0.2;  // a margin of 0.4: beyond the other layer for most points
  ProjectionResults made;
  ProjectionCounters counters;
  projector.project(PointView::of(anchors), making, made, {}, &counters);
  std::size_t clearance = 0;
  for (std::size_t i = 0; i < anchors.size(); ++i) {
    const WarmCertificate& c = made.certificate[i];
    if (c.radius > 0.0f) ADD_FAILURE() << "a certificate with a box at point " << i;
    if (!c.clearance_only()) continue;
    ++clearance;
    EXPECT_EQ(c.anchor, anchors[i].cast<float>());
    EXPECT_GT(double(c.clearance), made.distance[i]) << i;
    EXPECT_LE(double(c.clearance), made.distance[i] + 2.0 * making.certificate_radius + 1e-6) << i;
  }
  EXPECT_EQ(clearance, counters.certificates_made);
  EXPECT_GT(clearance, anchors.size() / 2);

  // Every point moved by up to 0.15 in a random direction (half of them towards the other
  // layer: along the normal, away from their foot), projected with the hints made above.
  std::mt19937_64 rng(17);
  std::vector<Vec3> queries(anchors.size());
  std::vector<ProjectionHint> hints(anchors.size());
  for (std::size_t i = 0; i < anchors.size(); ++i) {
    Vec3 direction(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    if (i % 2 == 0) direction = anchors[i] - made.foot[i];
    queries[i] = anchors[i] + uniform(rng, 0.0, 0.15) * direction.normalized();
    hints[i] = made.hint(i);
  }
  ProjectionResults warm, cold;
  ProjectionCounters warm_counters;
  projector.project(PointView::of(queries), {}, warm, hints, &warm_counters);
  projector.project(PointView::of(queries), {}, cold);
  // The cases a proof that left out the move would get wrong: P's own minimum within the
  // clearance, the model's answer nearer and elsewhere.
  std::size_t traps = 0;
  SurfaceScratch scratch;
  for (std::size_t i = 0; i < queries.size(); ++i) {
    ASSERT_EQ(warm.status[i], ProjectionStatus::ok);
    ASSERT_NEAR(warm.distance[i], cold.distance[i], 1e-12 * diagonal) << "point " << i;
    const WarmCertificate& c = hints[i].certificate;
    if (!c.clearance_only()) continue;
    SurfaceHit own;
    project_onto_patch(model.patch(static_cast<std::size_t>(c.patch)), queries[i], own, scratch);
    traps += std::sqrt(own.distance_sq) <= c.clearance &&
             cold.distance[i] < std::sqrt(own.distance_sq) - 1e-6;
  }
  EXPECT_GT(warm_counters.certified, queries.size() / 4);
  EXPECT_GT(traps, 20u) << "no point the move term must keep from a wrong proof";
  std::printf(
      "[ report ] %zu clearance certificates of %zu points; %llu moved points proven, %zu "
      "traps\n",
      clearance, anchors.size(), static_cast<unsigned long long>(warm_counters.certified), traps);
}

TEST(ClearanceCertificate, HintsOnTheWrongSlopeOfTheirOwnPatchStillGiveItsMinimum) {
  // One patch and nothing else: any clearance is a true statement ("nothing else within it"),
  // and every proof rests on P's own minimum.
  const PreparedModel model(test::model_of({test::trough()}));
  ASSERT_EQ(model.patch_count(), 1u);
  const double diagonal = model.bounds().diagonal();
  std::mt19937_64 points_rng(9);
  std::vector<Vec3> points;
  for (int k = 0; k < 2000; ++k) {
    points.emplace_back(5.0 + uniform(points_rng, -2.0, 2.0), uniform(points_rng, 1.0, 9.0),
                        uniform(points_rng, 13.0, 19.0));
  }
  Projector projector(model);
  ProjectionResults cold;
  projector.project(PointView::of(points), {}, cold);
  const BezierPatch& patch = model.patch(0).patch;
  std::mt19937_64 rng(3);
  std::vector<ProjectionHint> hints(points.size());
  std::size_t traps = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    // A random start on the patch; Newton from there alone stops at whichever slope's local
    // minimum it falls into.
    const double s = uniform(rng, 0.0, 1.0), t = uniform(rng, 0.0, 1.0);
    WarmCertificate c;
    c.anchor = points[i].cast<float>();
    c.patch = 0;
    c.clearance = static_cast<float>(10.0 * diagonal);
    c.model = model.serial();
    ASSERT_TRUE(c.clearance_only());
    hints[i] = ProjectionHint(0, patch.param_u.to_parent(s), patch.param_v.to_parent(t), c);
    double ns = s, nt = t;
    Vec3 foot;
    const double newton = newton_on_patch(patch, points[i], 0.0, 1.0, 0.0, 1.0, ns, nt, foot);
    traps += std::sqrt(newton) > cold.distance[i] + 1e-6;
  }
  ProjectionResults warm;
  ProjectionCounters counters;
  projector.project(PointView::of(points), {}, warm, hints, &counters);
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_NEAR(warm.distance[i], cold.distance[i], 1e-12 * diagonal) << "point " << i;
    // The certificate stays with the answer it proved.
    EXPECT_TRUE(warm.certificate[i].clearance_only()) << i;
  }
  EXPECT_EQ(counters.certified, points.size());
  EXPECT_EQ(counters.patches_visited, 0u) << "no search: the one patch was clipped in place";
  EXPECT_GT(traps, points.size() / 10) << "no hint whose Newton alone stops on the wrong slope";
}

TEST(ClearanceCertificate, AnotherModelsCertificateProvesNothing) {
  // The same geometry prepared twice: the certificates of one are not the other's.
  const PreparedModel model(test::model_of({test::hairpin(0.3)}));
  const PreparedModel copy(test::model_of({test::hairpin(0.3)}));
  const std::vector<Vec3> points = points_near(model, 500, 21);
  Projector projector(model);
  ProjectionOptions making;
  making.certify_clearance = true;
  making.certificate_radius = 0.2;
  ProjectionResults made;
  projector.project(PointView::of(points), making, made);
  std::vector<ProjectionHint> own(points.size()), foreign(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    own[i] = made.hint(i);
    foreign[i] = made.hint(i);
    foreign[i].certificate.model = copy.serial();
  }
  ProjectionResults warm;
  ProjectionCounters counters;
  projector.project(PointView::of(points), {}, warm, own, &counters);
  EXPECT_GT(counters.certified, points.size() / 2);
  projector.project(PointView::of(points), {}, warm, foreign, &counters);
  EXPECT_EQ(counters.certified, 0u);
}

}  // namespace
}  // namespace nurbsreg::engine
