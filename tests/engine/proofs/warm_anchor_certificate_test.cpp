// WarmCertificate (ProjectionOptions::certify), checked claim by claim against references that
// share nothing with it:
//  - convexity: for points q anywhere in the anchor's ball (its sphere included), the Hessian of
//    F_q = |S - q|^2 computed from the patch's own derivatives is positive definite on a grid
//    over the certificate's box N;
//  - clearance: no sample of a dense parameter grid of the model outside N is closer to the
//    anchor than the clearance;
//  - answers: warm queries that carry certificates (moves inside, on and beyond the radius, and
//    certificates of other points) give the brute-force distance (SurfaceReference), the same
//    as cold queries, and the certificate path is really taken (not vacuous).
// Models: a bicubic sheet with C0 creases (random knots of full multiplicity), a hairpin (two
// layers 0.3 apart: two near-equal minima everywhere between them), the same fold inside one
// degree-5 patch (the other layer is the anchor's own patch), two stacked sheets (the clearance
// must see the other surface), and the rational sphere (certified as G = N_q - m D). A ramp patch
// gives queries inside a certificate's ball whose answer lies on the same patch outside the box N.
// Two flat sheets with a hint on the farther one: the hinted patch, whose clipping the search
// skips, must still bound the clearance.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "proofs/warm_certificate.hpp"
#include "support/hard_surfaces.hpp"
#include "support/hessian_check.hpp"
#include "support/random_entities.hpp"
#include "support/surface_reference.hpp"

namespace nurbsreg::engine {
namespace {

using test::folded_patch;
using test::hairpin;
using test::hessian_positive_definite;
using test::model_of;
using test::uniform;
using test::wavy_sheet;

std::vector<Model> test_models() {
  std::vector<Model> models;
  models.push_back(model_of({test::random_surface(11, 3, 3, 9, 9, false)}));
  models.push_back(model_of({hairpin(0.3)}));
  models.push_back(model_of({folded_patch(0.8)}));
  NurbsSurface lower = test::random_surface(12, 3, 2, 7, 6, false);
  NurbsSurface upper = test::random_surface(12, 3, 2, 7, 6, false);
  for (Vec3& c : upper.control_points)
    c.z() += 0.6;
  models.push_back(model_of({lower, upper}));
  models.push_back(model_of({wavy_sheet(14, 1)}));
  models.push_back(model_of({wavy_sheet(12, 2)}));
  return models;
}

// Points near the model (offsets along the normal) and anywhere in its enlarged box.
std::vector<Vec3> query_points(const PreparedModel& pm, std::size_t count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const auto samples = sample_surfaces(pm.model(), count / 2 + 1, seed);
  const Aabb box = pm.bounds();
  const Vec3 extent = box.hi - box.lo;
  std::vector<Vec3> points;
  for (std::size_t i = 0; i < count; ++i) {
    if (i % 2 == 0) {
      const auto& s = samples[i / 2];
      points.push_back(s.point + s.normal * uniform(rng, -0.4, 0.4));
    } else {
      points.push_back(box.lo - 0.25 * extent +
                       Vec3(uniform(rng, 0, 1.5) * extent.x(), uniform(rng, 0, 1.5) * extent.y(),
                            uniform(rng, 0, 1.5) * extent.z()));
    }
  }
  return points;
}

Vec3 random_direction(std::mt19937_64& rng) {
  std::normal_distribution<double> gauss;
  Vec3 d(gauss(rng), gauss(rng), gauss(rng));
  return d.normalized();
}

// A patch's part of a certificate's box N, in its local parameters: patch (a + i, b + j) of the
// anchor patch (a, b)'s surface covers [i, i + 1] x [j, j + 1] of N's grid coordinates.
struct Piece {
  const PreparedPatch* pp;
  int i, j;
  double s0, s1, t0, t1;
};

std::vector<Piece> pieces_of(const PreparedModel& pm, const WarmCertificate& c) {
  std::vector<Piece> pieces;
  const int surface = pm.patch_surface(static_cast<std::size_t>(c.patch));
  const auto at = pm.patch_span(static_cast<std::size_t>(c.patch));
  // One patch further than N may reach (SpanCertificate::kReach), so that a box that overran
  // its limit would show as a piece here.
  constexpr int kLook = SpanCertificate::kReach + 1;
  for (int i = -kLook; i <= kLook; ++i) {
    for (int j = -kLook; j <= kLook; ++j) {
      const double s0 = std::max(0.0, double(c.s0) - i), s1 = std::min(1.0, double(c.s1) - i);
      const double t0 = std::max(0.0, double(c.t0) - j), t1 = std::min(1.0, double(c.t1) - j);
      if (!(s0 < s1) || !(t0 < t1)) continue;
      const std::int64_t k = pm.patch_at(surface, at.a + i, at.b + j);
      EXPECT_GE(k, 0) << "N leaves the surface";
      if (k >= 0) pieces.push_back({&pm.patch(static_cast<std::size_t>(k)), i, j, s0, s1, t0, t1});
    }
  }
  return pieces;
}

// Is (u, v) of `surface` in one of the pieces (of surface `pieces_surface`)?
bool in_pieces(const std::vector<Piece>& pieces, int pieces_surface, int surface, double u,
               double v) {
  if (surface != pieces_surface) return false;
  for (const Piece& piece : pieces) {
    const BezierPatch& patch = piece.pp->patch;
    if (u < patch.param_u.lo || u > patch.param_u.hi || v < patch.param_v.lo ||
        v > patch.param_v.hi) {
      continue;
    }
    const double s = patch.param_u.to_local(u), t = patch.param_v.to_local(v);
    if (s >= piece.s0 && s <= piece.s1 && t >= piece.t0 && t <= piece.t1) return true;
  }
  return false;
}

// The piece whose patch box holds (u, v) (ends included), the first such.
const Piece& piece_holding(const std::vector<Piece>& pieces, double u, double v) {
  for (const Piece& piece : pieces) {
    const BezierPatch& patch = piece.pp->patch;
    const double s = patch.param_u.to_local(u), t = patch.param_v.to_local(v);
    if (s >= piece.s0 - 1e-12 && s <= piece.s1 + 1e-12 && t >= piece.t0 - 1e-12 &&
        t <= piece.t1 + 1e-12) {
      return piece;
    }
  }
  ADD_FAILURE() << "the foot is in none of N's pieces";
  return pieces.front();
}

// The radius cap as a fraction of the model's diagonal (0: the default) and
// ProjectionOptions::certificate_span.
struct Claim {
  double cap;
  int span;
};
class WarmAnchorClaims : public ::testing::TestWithParam<Claim> {};

// With the wide cap the radius is set by the convexity test itself, so the ball's sphere is where
// the Hessian is closest to losing definiteness; with the widest span the boxes reach across
// several patches of the test models' narrow grids.
TEST_P(WarmAnchorClaims, ConvexityAndClearanceHoldAgainstSampling) {
  int checked = 0, edge_feet = 0, spanning = 0, wide = 0;
  for (const Model& model : test_models()) {
    const PreparedModel pm{Model(model)};
    Projector projector(pm);
    ProjectionOptions options;
    options.certify = true;
    options.certificate_radius = GetParam().cap * pm.bounds().diagonal();
    options.certificate_span = GetParam().span;
    const std::vector<Vec3> points = query_points(pm, 80, 5);
    ProjectionResults results;
    projector.project(PointView::of(points), options, results);
    ASSERT_EQ(results.certificate.size(), points.size());
    // The model sampled once: (surface, u, v) and the point.
    struct Sample {
      int surface;
      double u, v;
      Vec3 point;
    };
    std::vector<Sample> samples;
    const int n = 240;
    for (int k = 0; k < static_cast<int>(model.surfaces.size()); ++k) {
      const NurbsSurface& s = model.surfaces[k];
      for (int i = 0; i <= n; ++i) {
        for (int j = 0; j <= n; ++j) {
          const double u = s.domain_u().to_parent(double(i) / n);
          const double v = s.domain_v().to_parent(double(j) / n);
          samples.push_back({k, u, v, s.evaluate(u, v)});
        }
      }
    }
    const double diagonal = pm.bounds().diagonal();
    std::mt19937_64 rng(17);
    for (std::size_t i = 0; i < points.size(); ++i) {
      const WarmCertificate& c = results.certificate[i];
      if (!(c.radius > 0.0)) continue;
      ++checked;
      EXPECT_EQ(c.anchor, points[i].cast<float>());
      const Vec3 anchor = c.anchor.cast<double>();
      EXPECT_GT(c.clearance, results.distance[i]);
      EXPECT_EQ(pm.patch_surface(static_cast<std::size_t>(c.patch)), results.entity[i]);
      // N's pieces: N is given in the anchor patch's grid coordinates (the patch i spans after it
      // in u and j in v covers [i, i + 1] x [j, j + 1]), and may reach into its neighbours.
      const std::vector<Piece> pieces = pieces_of(pm, c);
      ASSERT_FALSE(pieces.empty());
      spanning += pieces.size() > 1;
      wide += std::any_of(pieces.begin(), pieces.end(),
                          [](const Piece& p) { return std::abs(p.i) > 1 || std::abs(p.j) > 1; });
      // The foot in grid coordinates: inside N, or on N's side (an edge foot's proof).
      const Piece& foot_piece = piece_holding(pieces, results.u[i], results.v[i]);
      const double foot_s = foot_piece.i + foot_piece.pp->patch.param_u.to_local(results.u[i]);
      const double foot_t = foot_piece.j + foot_piece.pp->patch.param_v.to_local(results.v[i]);
      const int s_edge = foot_s <= c.s0 ? 1 : (foot_s >= c.s1 ? -1 : 0);
      const int t_edge = foot_t <= c.t0 ? 1 : (foot_t >= c.t1 ? -1 : 0);
      edge_feet += s_edge != 0 || t_edge != 0;
      // For points in the ball, its sphere included: an inner foot's N has F convex; an edge
      // foot's N has F increasing away from the edge (or convex); and in every case no point of a
      // dense grid over N is below the smallest Newton minimum over N's pieces.
      for (int k = 0; k < 6; ++k) {
        const double reach = k == 0 ? 0.0 : (k < 4 ? c.radius : uniform(rng, 0, c.radius));
        const Vec3 q = anchor + reach * random_direction(rng);
        double minimum = std::numeric_limits<double>::infinity();
        for (const Piece& piece : pieces) {
          double s_min = 0.5 * (piece.s0 + piece.s1), t_min = 0.5 * (piece.t0 + piece.t1);
          Vec3 foot;
          bool stationary = false;
          minimum = std::min(
              minimum, newton_on_patch(piece.pp->patch, q, piece.s0, piece.s1, piece.t0, piece.t1,
                                       s_min, t_min, foot, nullptr, nullptr, &stationary));
          ASSERT_TRUE(stationary);
        }
        for (const Piece& piece : pieces) {
          const BezierPatch& patch = piece.pp->patch;
          for (int a = 0; a <= 24; ++a) {
            for (int b = 0; b <= 24; ++b) {
              const double s = piece.s0 + (piece.s1 - piece.s0) * (a / 24.0);
              const double t = piece.t0 + (piece.t1 - piece.t0) * (b / 24.0);
              const double f = (patch.evaluate(s, t) - q).squaredNorm();
              ASSERT_GE(f, minimum - 1e-12 * diagonal * diagonal)
                  << "point " << i << ": F below the Newton minimum on N by " << minimum - f
                  << " at (" << s << ", " << t << ") of piece (" << piece.i << ", " << piece.j
                  << "), |q - a| = " << reach;
              if (a % 3 != 0 || b % 3 != 0) continue;
              const bool convex = hessian_positive_definite(patch, q, s, t);
              if (s_edge == 0 && t_edge == 0) {
                ASSERT_TRUE(convex)
                    << "point " << i << ": not convex at (" << s << ", " << t << ") of piece ("
                    << piece.i << ", " << piece.j << "), |q - a| = " << reach;
              } else if (!convex) {
                Vec3 d[6];
                patch.derivatives(s, t, d);
                const Vec3 r = d[0] - q;
                if (s_edge != 0) {
                  ASSERT_GT(s_edge * r.dot(d[1]), 0.0)
                      << "point " << i << ": F not increasing away from its edge";
                }
                if (t_edge != 0) {
                  ASSERT_GT(t_edge * r.dot(d[2]), 0.0)
                      << "point " << i << ": F not increasing away from its edge";
                }
              }
            }
          }
        }
      }
      // Clearance: every model sample outside N is at least that far from the anchor.
      for (const Sample& sample : samples) {
        if (in_pieces(pieces, results.entity[i], sample.surface, sample.u, sample.v)) continue;
        ASSERT_GE((sample.point - anchor).norm(), c.clearance - 1e-12 * diagonal)
            << "point " << i << ": a sample outside N of patch " << c.patch
            << " is closer than the clearance";
      }
    }
  }
  EXPECT_GT(checked, 100) << "too few certificates to check";
  EXPECT_GT(edge_feet, 10) << "too few certificates for feet on an edge";
  EXPECT_GT(spanning, 10) << "too few certificates whose box spans patches";
  if (GetParam().span > 1) {
    EXPECT_GT(wide, 10) << "too few certificates whose box reaches beyond the foot's neighbours";
  }
  std::printf(
      "[ report ] %d certificates checked, %d with the foot on N's side, %d spanning "
      "patches, %d of them beyond the patches next to the foot's\n",
      checked, edge_feet, spanning, wide);
}

INSTANTIATE_TEST_SUITE_P(RadiusCaps, WarmAnchorClaims,
                         ::testing::Values(Claim{0.0, 1}, Claim{0.2, 1},
                                           Claim{0.2, kMaxCertificateSpan}));

class WarmAnchorAnswers : public ::testing::TestWithParam<Claim> {};

TEST_P(WarmAnchorAnswers, EqualBruteForce) {
  for (const Model& model : test_models()) {
    const PreparedModel pm{Model(model)};
    std::vector<test::SurfaceReference> references;
    for (const NurbsSurface& s : model.surfaces)
      references.emplace_back(s);
    const double diagonal = pm.bounds().diagonal();
    Projector projector(pm);
    ProjectionOptions options;
    options.certify = true;
    options.certificate_radius = GetParam().cap * diagonal;
    options.certificate_span = GetParam().span;
    const std::vector<Vec3> anchors = query_points(pm, 240, 9);
    ProjectionResults first;
    projector.project(PointView::of(anchors), options, first);
    // Moved points: inside the radius (most), exactly on it, just beyond it, far beyond it; and
    // hints carrying another point's certificate.
    std::mt19937_64 rng(23);
    std::vector<Vec3> moved(anchors.size());
    std::vector<ProjectionHint> hints(anchors.size());
    std::size_t inside = 0;
    for (std::size_t i = 0; i < anchors.size(); ++i) {
      const double r = first.certificate[i].radius > 0.0 ? first.certificate[i].radius : 0.01;
      const int kind = static_cast<int>(i % 6);
      const double reach = kind < 3 ? uniform(rng, 0, r) : (kind == 3 ? r : 1.5 * r);
      moved[i] = anchors[i] + reach * random_direction(rng);
      hints[i] = kind == 5 ? first.hint((i * 7 + 3) % anchors.size()) : first.hint(i);
      if (kind == 4) moved[i] += 2.0 * random_direction(rng);
      inside += kind < 4 && first.certificate[i].radius > 0.0;
    }
    ProjectionCounters counters;
    ProjectionResults warm, cold;
    projector.project(PointView::of(moved), options, warm, hints, &counters);
    projector.project(PointView::of(moved), ProjectionOptions{}, cold);
    for (std::size_t i = 0; i < moved.size(); ++i) {
      double reference = std::numeric_limits<double>::infinity();
      for (const auto& r : references)
        reference = std::min(reference, std::sqrt(r.closest(moved[i]).distance_sq));
      ASSERT_EQ(warm.status[i], ProjectionStatus::ok);
      EXPECT_NEAR(warm.distance[i], cold.distance[i], 1e-10 * diagonal) << "point " << i;
      EXPECT_LE(warm.distance[i], reference + 1e-10 * diagonal) << "point " << i;
      EXPECT_NEAR((warm.foot[i] - moved[i]).norm(), warm.distance[i], 1e-12 * diagonal);
    }
    // Many queries inside their anchors' radius are answered by the certificate (the wider
    // radius cap makes wider moves, which the clearance then rejects more often).
    EXPECT_GT(counters.certified, inside / 4) << counters.certified << " of " << inside;
    std::printf("[ report ] %zu surfaces: %llu of %zu queries certified (%zu inside a radius)\n",
                model.surfaces.size(), static_cast<unsigned long long>(counters.certified),
                moved.size(), inside);
  }
}

INSTANTIATE_TEST_SUITE_P(RadiusCaps, WarmAnchorAnswers,
                         ::testing::Values(Claim{0.0, 1}, Claim{0.03, 1},
                                           Claim{0.03, kMaxCertificateSpan}));

// A borrowed certificate's Newton may start where the tangent plane at the anchor's foot puts the
// query's foot (newton_on_certificate_box's `predict`): the same minimum on N as from the foot
// itself, for queries across the ball, on boxes that span patches.
TEST(WarmAnchorCertificate, APredictedStartFindsTheSameMinimumOnN) {
  int compared = 0, elsewhere = 0;
  for (const Model& model : test_models()) {
    const PreparedModel pm{Model(model)};
    const double diagonal = pm.bounds().diagonal();
    ProjectionOptions options;
    options.certify = true;
    options.certificate_radius = 0.03 * diagonal;
    options.certificate_span = kMaxCertificateSpan;
    const std::vector<Vec3> anchors = query_points(pm, 240, 31);
    ProjectionResults first;
    Projector(pm).project(PointView::of(anchors), options, first);
    std::mt19937_64 rng(32);
    for (std::size_t i = 0; i < anchors.size(); ++i) {
      const WarmCertificate& c = first.certificate[i];
      if (!(c.radius > 0.0f) || c.patch < 0) continue;
      const BezierPatch& bp = pm.patch(static_cast<std::size_t>(c.patch)).patch;
      const double s_foot = std::clamp(bp.param_u.to_local(first.u[i]), 0.0, 1.0);
      const double t_foot = std::clamp(bp.param_v.to_local(first.v[i]), 0.0, 1.0);
      for (int k = 0; k < 4; ++k) {
        const Vec3 q = anchors[i] + uniform(rng, 0.2, 1.0) * c.radius * random_direction(rng);
        double f[2];
        std::int64_t patch[2];
        Vec3 foot[2];
        bool stationary[2];
        for (int predict = 0; predict < 2; ++predict) {
          patch[predict] = c.patch;
          double s = s_foot, t = t_foot;
          Vec3 normal;
          f[predict] = newton_on_certificate_box(pm, c.patch, c.s0, c.s1, c.t0, c.t1, q,
                                                 patch[predict], s, t, foot[predict], normal,
                                                 stationary[predict], predict == 1);
        }
        if (!stationary[0] || !stationary[1]) continue;
        ++compared;
        elsewhere += patch[0] != c.patch;
        EXPECT_NEAR(std::sqrt(f[1]), std::sqrt(f[0]), 1e-10 * diagonal) << "point " << i;
        EXPECT_LE((foot[1] - foot[0]).norm(), 1e-6 * diagonal) << "point " << i;
      }
    }
  }
  EXPECT_GT(compared, 200);
  EXPECT_GT(elsewhere, 20) << "too few queries whose foot lies on another patch of N";
}

// One bicubic patch, flat along x for most of it, then ramping up 6 units over its last third:
// F is not convex over the whole patch for points above the ramp's bowl, so their certificates'
// boxes N are sub-boxes, while the flat and gently curved parts give them wide radii.
NurbsSurface ramp() {
  return test::bicubic_patch(
      "ramp", [](int i, int j) { return Vec3(2.0 * i, 2.0 * j, i == 3 ? 6.0 : 0.0); });
}

// A query inside a certificate's ball whose closest point is on the certificate's own patch but
// outside its box N: the certificate proves nothing, and the patch must still be searched (its
// Newton on N only gave an upper bound). Moves of up to the radius from anchors above the ramp;
// each answer against brute force, and the decisive cases (N's own minimum is not the answer)
// must occur.
TEST(WarmAnchorCertificate, AnswersOnTheSamePatchOutsideTheBoxStayExact) {
  const NurbsSurface surface = ramp();
  const PreparedModel pm{model_of({surface})};
  const test::SurfaceReference reference(surface);
  const BezierPatch& patch = pm.patch(0).patch;
  Projector projector(pm);
  ProjectionOptions options;
  options.certify = true;
  options.certificate_radius = 0.5 * pm.bounds().diagonal();
  const double tolerance = 1e-9 * pm.bounds().diagonal();
  int sub_boxes = 0, decisive = 0;
  for (const double x : {1.0, 3.0, 5.0}) {
    for (const double z : {3.0, 5.0, 7.0}) {
      const std::vector<Vec3> anchor{Vec3(x, 3.0, z)};
      ProjectionResults made;
      projector.project(PointView::of(anchor), options, made);
      const WarmCertificate& c = made.certificate[0];
      if (!(c.radius > 0.0f) || (c.s0 == 0.0f && c.s1 == 1.0f && c.t0 == 0.0f && c.t1 == 1.0f)) {
        continue;
      }
      ++sub_boxes;
      for (const Vec3& direction : {Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1),
                                    Vec3(0, 0, -1), Vec3(1, 1, 1).normalized()}) {
        for (const double fraction : {0.3, 0.6, 0.9, 1.0}) {
          const std::vector<Vec3> query{anchor[0] + fraction * c.radius * direction};
          const std::vector<ProjectionHint> hint{made.hint(0)};
          ProjectionResults warm;
          projector.project(PointView::of(query), ProjectionOptions{}, warm, hint);
          const test::ReferenceHit exact = reference.closest(query[0]);
          ASSERT_EQ(warm.status[0], ProjectionStatus::ok);
          EXPECT_NEAR(warm.distance[0], std::sqrt(exact.distance_sq), tolerance)
              << "anchor " << anchor[0].transpose() << ", query " << query[0].transpose();
          // Decisive: N's own minimum (a Newton on N, as the warm path runs it) is not the answer.
          double s = std::clamp(patch.param_u.to_local(made.u[0]), double(c.s0), double(c.s1));
          double t = std::clamp(patch.param_v.to_local(made.v[0]), double(c.t0), double(c.t1));
          Vec3 foot;
          const double on_n = std::sqrt(
              newton_on_patch(patch, query[0], c.s0, c.s1, c.t0, c.t1, s, t, foot, nullptr));
          if (on_n > std::sqrt(exact.distance_sq) + 1e3 * tolerance) ++decisive;
        }
      }
    }
  }
  EXPECT_GE(sub_boxes, 2);
  EXPECT_GE(decisive, 4);
  std::printf("[ report ] %d certificates on sub-boxes, %d queries answered outside N\n", sub_boxes,
              decisive);
}

// A flat bicubic sheet over [0, 1]^2 at height z (uniform control points: F is quadratic and
// convex for every point, so a hint on it skips the sheet's clipping).
NurbsSurface flat_sheet(double z) {
  return test::bicubic_patch("sheet", [z](int i, int j) { return Vec3(i / 3.0, j / 3.0, z); });
}

TEST(WarmAnchorCertificate, TheHintedSurfaceCountsInTheClearance) {
  // Between two sheets 1 apart, 0.05 nearer the upper one, with a hint on the lower one: the
  // hinted patch is proven convex, so the search skips its clipping and its minimum (0.55) comes
  // from the hint. The answer is the upper sheet (0.45); with the radius cap at 0.2 the search
  // bounds the rest up to 0.45 + 0.4 = 0.85, so the lower sheet must limit the clearance.
  const PreparedModel pm{model_of({flat_sheet(0.0), flat_sheet(1.0)})};
  const std::vector<Vec3> points = {Vec3(0.5, 0.5, 0.55), Vec3(0.3, 0.6, 0.52),
                                    Vec3(0.7, 0.2, 0.58)};
  std::vector<ProjectionHint> hints;
  for (const Vec3& p : points)
    hints.emplace_back(0, p.x(), p.y());
  ProjectionOptions options;
  options.certify = true;
  options.certificate_radius = 0.2;
  Projector projector(pm);
  ProjectionResults results;
  projector.project(PointView::of(points), options, results, hints);
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_EQ(results.entity[i], 1) << i;
    EXPECT_NEAR(results.distance[i], 1.0 - points[i].z(), 1e-12) << i;
    const WarmCertificate& c = results.certificate[i];
    ASSERT_GT(c.radius, 0.0f) << i;  // the check below is not vacuous
    // The lower sheet is outside N (another surface): the clearance is at most its distance from
    // the anchor.
    EXPECT_LE(double(c.clearance), double(c.anchor.z()) + 1e-12) << i;
  }
}

TEST(WarmAnchorCertificate, SameCertificatesForAnyThreadCount) {
  const Model model = test_models().front();
  const PreparedModel pm{Model(model)};
  const std::vector<Vec3> points = query_points(pm, 400, 3);
  ProjectionOptions options;
  options.certify = true;
  options.grain = 16;
  ProjectionResults serial, parallel;
  Projector a(pm), b(pm);
  a.project_serial(PointView::of(points), options, serial);
  {
    tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
    b.project(PointView::of(points), options, parallel);
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(serial.distance[i], parallel.distance[i]);
    EXPECT_EQ(serial.certificate[i].radius, parallel.certificate[i].radius);
    EXPECT_EQ(serial.certificate[i].clearance, parallel.certificate[i].clearance);
    EXPECT_EQ(serial.certificate[i].patch, parallel.certificate[i].patch);
  }
}

TEST(WarmAnchorCertificate, CertificatesOfAnotherModelAreNotTrusted) {
  // The same patch layout, the geometry moved by 0.05: a certificate made for `a` proves
  // nothing about `b`, and `b` must not use it.
  NurbsSurface surface = test::random_surface(11, 3, 3, 9, 9, false);
  const PreparedModel a{model_of({surface})};
  for (Vec3& c : surface.control_points)
    c.z() += 0.05;
  const PreparedModel b{model_of({surface})};
  ASSERT_NE(a.serial(), b.serial());
  const std::vector<Vec3> points = query_points(a, 200, 6);
  ProjectionOptions options;
  options.certify = true;
  ProjectionResults made, warm, cold;
  Projector pa(a), pb(b);
  pa.project(PointView::of(points), options, made);
  std::vector<ProjectionHint> hints;
  for (std::size_t i = 0; i < points.size(); ++i)
    hints.push_back(made.hint(i));
  ProjectionCounters counters;
  pb.project(PointView::of(points), ProjectionOptions{}, warm, hints, &counters);
  pb.project(PointView::of(points), ProjectionOptions{}, cold);
  EXPECT_EQ(counters.certified, 0u);
  for (std::size_t i = 0; i < points.size(); ++i)
    EXPECT_NEAR(warm.distance[i], cold.distance[i], 1e-12 * b.bounds().diagonal()) << i;
}

// Rational patches (the sphere: every patch rational) get certificates for G = N_q - m D
// (warm_certificate.cpp): every answer, certified or searched, is the closed form, for moves of
// 0.5, 0.99 and 1.5 times each certificate's radius; and they prove answers (not vacuous).
TEST(WarmAnchorCertificate, RationalSurfacesCertifiedAndExact) {
  const Vec3 centre(1, 2, 3);
  const double radius = 5.0;
  const PreparedModel pm{model_of({make_sphere(centre, radius)})};
  std::vector<Vec3> points = query_points(pm, 200, 4);
  Projector projector(pm);
  ProjectionOptions options;
  options.certify = true;
  options.certificate_radius = 0.2;
  ProjectionResults made, warm;
  ProjectionCounters made_counters, counters;
  projector.project(PointView::of(points), options, made, {}, &made_counters);
  EXPECT_GT(made_counters.certificates_made, points.size() / 4);
  std::mt19937_64 rng(41);
  std::vector<ProjectionHint> hints;
  const double factors[3] = {0.5, 0.99, 1.5};
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_NEAR(made.distance[i], std::abs((points[i] - centre).norm() - radius), 1e-9);
    hints.push_back(made.hint(i));
    const double r = made.certificate[i].radius;
    points[i] += (r > 0.0 ? factors[i % 3] * r : 0.01) * random_direction(rng);
  }
  projector.project(PointView::of(points), ProjectionOptions{}, warm, hints, &counters);
  EXPECT_GT(counters.certified, points.size() / 8);
  for (std::size_t i = 0; i < points.size(); ++i)
    EXPECT_NEAR(warm.distance[i], std::abs((points[i] - centre).norm() - radius), 1e-9) << i;
}

// On a long rational strip a certificate's radius comes from how G = N_q - m D moves with the
// query over the box N: bounded with the second differences of E' = w (P - a) and D restricted to
// N, it is about a tenth of the cylinder's radius (0.48 here); bounded with the whole patch's,
// scaled by N's widths, E' carried the strip's length (the control rows 200 from a mid-strip
// anchor along the axis) and it was 0.017. Checked: moves of 0.5, 0.99 and 1.5 times what each
// certificate serves and 0.9 of its radius give the brute-force answer (SurfaceReference); the
// certificates are made and prove answers.
TEST(WarmAnchorCertificate, LongRationalStripsGetWideCertificatesThatHold) {
  const double radius = 5.0, length = 400.0;
  const NurbsSurface strip = test::cylinder_strip(radius, length);
  const PreparedModel pm{model_of({strip})};
  ASSERT_TRUE(pm.patch(0).rational);
  const test::SurfaceReference reference(strip);
  // Points off the surface by up to 0.05 on both sides, away from the strip's ends.
  std::mt19937_64 rng(61);
  std::vector<Vec3> points;
  for (int k = 0; k < 120; ++k) {
    const double angle = uniform(rng, 0.15, 0.5 * M_PI - 0.15);
    const double rho = radius + uniform(rng, -0.05, 0.05);
    points.emplace_back(rho * std::cos(angle), rho * std::sin(angle),
                        uniform(rng, -0.4, 0.4) * length);
  }
  Projector projector(pm);
  ProjectionOptions options;
  options.certify = true;
  options.certificate_radius = 20.0;  // ICP's cap on a part a hundred times the bore
  ProjectionResults made;
  projector.project(PointView::of(points), options, made);
  std::vector<double> radii;
  std::vector<ProjectionHint> hints;
  std::vector<Vec3> moved;
  const double factors[3] = {0.5, 0.99, 1.5};
  for (std::size_t i = 0; i < points.size(); ++i) {
    const WarmCertificate& w = made.certificate[i];
    radii.push_back(w.radius);
    const double serves =
        std::min<double>(w.radius, 0.5 * (double(w.clearance) - made.distance[i]));
    const double step = !(w.radius > 0.0f) ? 0.1
                        : i % 4 == 3       ? 0.9 * w.radius
                                           : factors[i % 4] * serves;
    moved.push_back(points[i] + step * random_direction(rng));
    hints.push_back(made.hint(i));
  }
  std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
  const double median = radii[radii.size() / 2];
  std::printf("[ report ] rational strip: median certificate radius %.3g (cylinder radius %.3g)\n",
              median, radius);
  EXPECT_GE(median, 0.05 * radius);
  ProjectionCounters counters;
  ProjectionResults warm;
  projector.project(PointView::of(moved), ProjectionOptions{}, warm, hints, &counters);
  EXPECT_GT(counters.certified, moved.size() / 4);
  for (std::size_t i = 0; i < moved.size(); ++i) {
    ASSERT_EQ(warm.status[i], ProjectionStatus::ok);
    EXPECT_NEAR(warm.distance[i], std::sqrt(reference.closest(moved[i]).distance_sq), 1e-9)
        << "point " << i << ", certificate radius " << made.certificate[i].radius;
  }
}

TEST(WarmAnchorCertificate, MaxDistanceStillApplies) {
  const Model model = test_models().front();
  const PreparedModel pm{Model(model)};
  const std::vector<Vec3> points = query_points(pm, 60, 8);
  Projector projector(pm);
  ProjectionOptions options;
  options.certify = true;
  ProjectionResults first, second;
  projector.project(PointView::of(points), options, first);
  std::vector<ProjectionHint> hints;
  for (std::size_t i = 0; i < points.size(); ++i)
    hints.push_back(first.hint(i));
  options.max_distance = 0.2;
  projector.project(PointView::of(points), options, second, hints);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (first.distance[i] < 0.2) {
      EXPECT_EQ(second.status[i], ProjectionStatus::ok);
      EXPECT_NEAR(second.distance[i], first.distance[i], 1e-12 * pm.bounds().diagonal());
    } else {
      EXPECT_EQ(second.status[i], ProjectionStatus::beyond_max_distance) << "point " << i;
    }
  }
}

}  // namespace
}  // namespace nurbsreg::engine

namespace nurbsreg::engine {
namespace {

// A bicubic V: two planar flanks z = 1.5 |x| meeting in a crease at x = 0 (u = 1/2, a knot of
// full multiplicity: C0 there), so F is convex on each flank but not across the crease.
NurbsSurface crease_v() {
  NurbsSurface s;
  s.name = "V";
  s.degree_u = 3;
  s.degree_v = 3;
  s.count_u = 7;
  s.count_v = 4;
  s.knots_u = {0, 0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1, 1};
  s.knots_v = {0, 0, 0, 0, 1, 1, 1, 1};
  for (int i = 0; i < s.count_u; ++i) {
    for (int j = 0; j < s.count_v; ++j) {
      const double x = i - 3.0;
      s.control_points.emplace_back(x, j, 1.5 * std::abs(x));
    }
  }
  return s;
}

// Above the crease, just right of it: the right flank is nearer, the left one nearly as near.
// A certificate whose box spanned both flanks (both convex, so each piece's test holds) would
// call the right flank's Newton minimum the answer for a point moved just left of the crease,
// where the left flank is nearer. The crease must stop the box (PreparedModel::surface_c1).
TEST(WarmAnchorCertificate, BoxesDoNotSpanACrease) {
  const NurbsSurface surface = crease_v();
  const PreparedModel pm{model_of({surface})};
  ASSERT_FALSE(pm.surface_c1(0));
  ASSERT_EQ(pm.patch_count(), 2u);
  const test::SurfaceReference reference(surface);
  Projector projector(pm);
  ProjectionOptions options;
  options.certify = true;
  options.certificate_radius = 1.0;
  for (const double y : {0.5, 1.5, 2.5}) {
    for (const double z : {1.0, 2.0, 3.0}) {
      const std::vector<Vec3> anchor{Vec3(0.01, y, z)};
      ProjectionResults made;
      projector.project(PointView::of(anchor), options, made);
      ASSERT_GT(made.u[0], 0.5);  // the right flank
      const std::vector<Vec3> query{Vec3(-0.05, y, z)};
      const std::vector<ProjectionHint> hint{made.hint(0)};
      ProjectionResults warm;
      projector.project(PointView::of(query), ProjectionOptions{}, warm, hint);
      const test::ReferenceHit exact = reference.closest(query[0]);
      ASSERT_EQ(warm.status[0], ProjectionStatus::ok);
      EXPECT_NEAR(warm.distance[0], std::sqrt(exact.distance_sq), 1e-9) << "z = " << z;
      EXPECT_LT(warm.u[0], 0.5) << "z = " << z;
      // The right flank's plane (1.5 x - z = 0) is farther than the answer: the case decides.
      const double right_flank = std::abs(1.5 * query[0].x() - query[0].z()) / std::sqrt(3.25);
      EXPECT_GT(right_flank - std::sqrt(exact.distance_sq), 0.05);
    }
  }
}

}  // namespace
}  // namespace nurbsreg::engine
