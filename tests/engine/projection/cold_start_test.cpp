// The cold path's shortcuts against independent references: the oriented-box lower bound of
// PreparedModel::item_lower_bound never exceeds a patch's true distance (dense samples of the
// patch bound that from above), and cold projections whose answer is a panel corner, a boundary
// edge, a seed sample point of the grid (PreparedModel::seed_from_grid: 5 x 5 samples per patch)
// or anything else are never farther than a brute force (test::SurfaceReference) and are
// surface points at the reported parameters, on polynomial and rational surfaces.
#include <gtest/gtest.h>

#include <random>

#include "model/bvh.hpp"
#include "model/prepared_model_internals.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "support/polygon_loop.hpp"
#include "support/random_entities.hpp"
#include "support/surface_reference.hpp"

namespace nurbsreg::engine {
namespace {

using test::uniform;

Model single_surface_model(const NurbsSurface& s) {
  Model m;
  m.surfaces.push_back(s);
  return m;
}

// Points near and far from patch k of `model`: on the patch and off it along the normal by
// tiny to large offsets, and anywhere in the enlarged model box.
std::vector<Vec3> points_around_patch(const PreparedModel& model, std::size_t k,
                                      std::mt19937_64& rng) {
  const BezierPatch& bp = model.patch(k).patch;
  const Aabb& box = model.bounds();
  const double size = box.diagonal();
  std::vector<Vec3> points;
  for (int n = 0; n < 12; ++n) {
    const double s = uniform(rng, 0, 1), t = uniform(rng, 0, 1);
    Vec3 d[6];
    bp.derivatives(s, t, d);
    const Vec3 normal = d[1].cross(d[2]).normalized();
    for (double offset : {0.0, 1e-9, -1e-6, 1e-3, -0.02, 0.1, -0.5}) {
      points.push_back(d[0] + offset * size * (normal.allFinite() ? normal : Vec3::UnitZ()));
    }
  }
  const Vec3 lo = box.lo - 0.5 * (box.hi - box.lo), hi = box.hi + 0.5 * (box.hi - box.lo);
  for (int n = 0; n < 20; ++n) {
    points.push_back(test::uniform_point(rng, lo, hi));
  }
  return points;
}

TEST(ColdStart, OrientedBoxBoundNeverExceedsThePatchDistance) {
  std::vector<NurbsSurface> surfaces = {
      test::random_surface(3, 3, 3, 9, 9, false), test::random_surface(4, 3, 2, 7, 8, true),
      make_sphere(Vec3(1, 2, 3), 2.0), make_torus(Vec3(0, 0, 0), 3.0, 0.7)};
  std::mt19937_64 rng(17);
  for (const NurbsSurface& surface : surfaces) {
    const PreparedModel model(single_surface_model(surface));
    ASSERT_EQ(model.hierarchy_patch_items(), model.patch_count());
    for (std::uint32_t k = 0; k < model.hierarchy_patch_items(); ++k) {
      const BezierPatch& bp = model.patch(model.item_patch(k)).patch;
      // Dense samples of the patch: their smallest squared distance is >= the true one.
      constexpr int kGrid = 24;
      std::vector<Vec3> samples;
      for (int a = 0; a <= kGrid; ++a) {
        for (int b = 0; b <= kGrid; ++b)
          samples.push_back(bp.evaluate(double(a) / kGrid, double(b) / kGrid));
      }
      for (const Vec3& p : points_around_patch(model, model.item_patch(k), rng)) {
        double sampled = std::numeric_limits<double>::infinity();
        for (const Vec3& x : samples)
          sampled = std::min(sampled, (x - p).squaredNorm());
        const double bound = model.item_lower_bound(k, p);
        EXPECT_LE(bound, sampled * (1.0 + 1e-12) + 1e-24)
            << surface.name << " patch " << k << " point " << p.transpose();
      }
    }
  }
}

// A bench-like panel (bicubic, 10 x 10 control points, 49 patches), polynomial or rational.
NurbsSurface panel(bool rational) {
  NurbsSurface s = test::random_surface(rational ? 23 : 22, 3, 3, 10, 10, rational);
  s.name = rational ? "rational panel" : "panel";
  return s;
}

// Points whose closest point is a corner of the panel, a point of its boundary, one of the seed
// samples (local (s, t) on the 5 x 5 grid of a patch) or anything else.
std::vector<Vec3> hard_cold_points(const PreparedModel& model, std::mt19937_64& rng) {
  const NurbsSurface& s = model.model().surfaces[0];
  const Aabb& box = model.bounds();
  const double size = box.diagonal();
  std::vector<Vec3> points;
  const double us[2] = {s.domain_u().lo, s.domain_u().hi};
  const double vs[2] = {s.domain_v().lo, s.domain_v().hi};
  for (int a = 0; a < 2; ++a) {
    for (int b = 0; b < 2; ++b) {
      // Beyond the corner: outward along both boundary tangents and the normal.
      const SurfaceDerivatives d = s.derivatives(us[a], vs[b]);
      const Vec3 out_u = (a == 0 ? -1.0 : 1.0) * d.su.normalized();
      const Vec3 out_v = (b == 0 ? -1.0 : 1.0) * d.sv.normalized();
      const Vec3 normal = d.su.cross(d.sv).normalized();
      for (double h : {0.01, 0.1, 0.4})
        points.push_back(d.s + h * size * (out_u + out_v + uniform(rng, -0.5, 0.5) * normal));
    }
  }
  for (int n = 0; n < 24; ++n) {
    // Beyond a boundary edge.
    const int edge = n % 4;
    const double x = uniform(rng, 0.05, 0.95);
    const double u = edge < 2 ? us[edge] : s.domain_u().to_parent(x);
    const double v = edge < 2 ? s.domain_v().to_parent(x) : vs[edge - 2];
    const SurfaceDerivatives d = s.derivatives(u, v);
    const Vec3 out = edge < 2 ? (edge == 0 ? -1.0 : 1.0) * d.su.normalized()
                              : (edge == 2 ? -1.0 : 1.0) * d.sv.normalized();
    const Vec3 normal = d.su.cross(d.sv).normalized();
    points.push_back(d.s + uniform(rng, 0.01, 0.3) * size * (out + uniform(rng, -1, 1) * normal));
  }
  for (std::size_t k = 0; k < model.patch_count(); k += 3) {
    // Off a seed sample along the normal: the seed point itself may be the answer.
    const BezierPatch& bp = model.patch(k).patch;
    const double s_loc = 0.25 * double(k % 5), t_loc = 0.25 * double((k / 5) % 5);
    Vec3 d[6];
    bp.derivatives(s_loc, t_loc, d);
    const Vec3 normal = d[1].cross(d[2]).normalized();
    for (double h : {0.0, 1e-4, -0.01})
      points.push_back(d[0] + h * size * normal);
  }
  const Vec3 lo = box.lo - 0.25 * (box.hi - box.lo), hi = box.hi + 0.25 * (box.hi - box.lo);
  for (int n = 0; n < 60; ++n) {
    points.push_back(test::uniform_point(rng, lo, hi));
  }
  return points;
}

TEST(ColdStart, ColdProjectionNoWorseThanBruteForceAtCornersEdgesAndSeeds) {
  std::mt19937_64 rng(5);
  for (bool rational : {false, true}) {
    const PreparedModel model(single_surface_model(panel(rational)));
    const NurbsSurface& s = model.model().surfaces[0];
    const test::SurfaceReference reference(s, 400, 4000, 400);
    const std::vector<Vec3> points = hard_cold_points(model, rng);
    Projector projector(model);
    ProjectionResults results;
    projector.project(PointView::of(points), {}, results);
    const double tolerance = 1e-9 * model.bounds().diagonal();
    for (std::size_t i = 0; i < points.size(); ++i) {
      ASSERT_EQ(results.status[i], ProjectionStatus::ok);
      // Never farther than the brute force; it may be closer where the sampled reference misses
      // a minimum (it does on this wavy panel), so the answer's own consistency is checked too: a
      // surface point at the reported parameters and distance.
      const test::ReferenceHit ref = reference.closest(points[i]);
      EXPECT_LE(results.distance[i], std::sqrt(ref.distance_sq) + tolerance)
          << s.name << " point " << i << " " << points[i].transpose();
      EXPECT_LT((s.evaluate(results.u[i], results.v[i]) - results.foot[i]).norm(), tolerance)
          << s.name << " point " << i;
      EXPECT_NEAR((points[i] - results.foot[i]).norm(), results.distance[i], tolerance);
      EXPECT_NEAR(results.normal[i].norm(), 1.0, 1e-12);
    }
  }
}

// PreparedModel::item_bound (the bound a near list orders its items by) repeats the rule the
// hierarchy walk orders its leaves by: the larger of the item's box distance and
// item_lower_bound. The walk, told each leaf's bound, must agree with it to the bit for every
// item it reaches (all of them: alpha stays infinite), on patches and on trim-edge pieces.
TEST(ColdStart, ItemBoundIsTheHierarchyWalksLeafBound) {
  std::mt19937_64 rng(11);
  for (bool rational : {false, true}) {
    Model m = single_surface_model(panel(rational));
    // A trimmed copy beside it: edge pieces join the items.
    NurbsSurface trimmed = panel(rational);
    const auto& ku = trimmed.knots_u;
    const auto& kv = trimmed.knots_v;
    const double u0 = ku.front(), u1 = ku.back(), v0 = kv.front(), v1 = kv.back();
    trimmed.trim_loops.push_back(
        test::polygon_loop({{u0 + 0.1 * (u1 - u0), v0 + 0.2 * (v1 - v0)},
                            {u0 + 0.9 * (u1 - u0), v0 + 0.1 * (v1 - v0)},
                            {u0 + 0.6 * (u1 - u0), v0 + 0.9 * (v1 - v0)}}));
    for (Vec3& c : trimmed.control_points)
      c.z() += 0.5;
    m.surfaces.push_back(trimmed);
    const PreparedModel model(m);
    ASSERT_GT(model.patch_hierarchy().order().size(), model.hierarchy_patch_items());
    const Aabb box = model.bounds();
    const Vec3 lo = box.lo - 0.5 * (box.hi - box.lo), hi = box.hi + 0.5 * (box.hi - box.lo);
    Bvh::Scratch scratch;
    std::size_t checked = 0;
    for (int n = 0; n < 200; ++n) {
      const Vec3 p = test::uniform_point(rng, lo, hi);
      double alpha = std::numeric_limits<double>::infinity();
      std::size_t reached = 0;
      model.patch_hierarchy().nearest(
          p, alpha, scratch,
          [&](std::uint32_t k, const Vec3& x) { return model.item_lower_bound(k, x); },
          [&](std::uint32_t k, double&, double bound) {
            ++reached;
            EXPECT_EQ(bound, model.item_bound(k, p)) << "item " << k << " point " << p.transpose();
          });
      EXPECT_EQ(reached, model.patch_hierarchy().order().size());
      checked += reached;
    }
    EXPECT_GT(checked, 0u);
  }
}

}  // namespace
}  // namespace nurbsreg::engine
