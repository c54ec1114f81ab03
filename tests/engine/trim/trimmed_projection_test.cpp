// Exact projection onto trimmed faces through PreparedModel + Projector (issue 7), against
// independent references: closed forms where they exist (a flat panel with a circular hole made
// of rational quadratic uv arcs; points at a sphere's centre), else a brute-force search of the
// trimmed face (dense (u, v) samples inside the region, each polished by a bounded Newton that
// stays inside, plus dense samples of every boundary edge refined by golden section). Both
// directions are checked: our distance is not above the reference's (we miss nothing), and our
// foot is a face point (inside the region or on an edge) at the reported distance (we do not
// "win" with a point of a hole).

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/engine/trim_region.hpp"
#include "support/example_surface.hpp"
#include "support/golden_section.hpp"
#include "support/polygon_loop.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

constexpr double kPi = 3.14159265358979323846;

using test::polygon_loop;
using test::rectangle_loop;
using test::uv_line;

// A star with `tips` points around c (radii alternating r_out, r_in), rotated by `phase`.
TrimLoop star_loop(const Vec2& c, double r_in, double r_out, int tips, double phase) {
  std::vector<Vec2> corners;
  for (int k = 0; k < 2 * tips; ++k) {
    const double a = phase + kPi * k / tips;
    const double r = k % 2 == 0 ? r_out : r_in;
    corners.emplace_back(c.x() + r * std::cos(a), c.y() + r * std::sin(a));
  }
  return polygon_loop(corners);
}

// ---------------------------------------------------------------------------------------------
// The flat panel: the plane z = 0 over [0, 10]^2 as a bicubic B-spline with 3 x 3 spans and a
// linear parametrisation (control points at the Greville abscissae), so S(u, v) = (10u, 10v, 0).
// Face: the square [0.05, 0.95]^2 minus the disc of radius 0.2 about (0.45, 0.55) in (u, v),
// i.e. [0.5, 9.5]^2 minus the disc of radius 2 about (4.5, 5.5) in the plane. The hole is a
// rational quadratic circle (4 arcs) with its exact 3-D edge given, as a CAD file would.

constexpr double kSquareLo = 0.5, kSquareHi = 9.5;
const Vec2 kHoleCentre(4.5, 5.5);
constexpr double kHoleRadius = 2.0;

// inset: the outer loop's distance from the domain's border in (u, v); 0 puts the loop on the
// domain's own border (the region's boundary is then both a loop and the domain's edge).
NurbsSurface flat_panel(double inset = 0.05) {
  NurbsSurface s;
  s.name = "flat panel";
  s.degree_u = s.degree_v = 3;
  s.knots_u = s.knots_v = {0, 0, 0, 0, 1.0 / 3.0, 2.0 / 3.0, 1, 1, 1, 1};
  s.count_u = s.count_v = 6;
  const double greville[6] = {0.0, 1.0 / 9.0, 1.0 / 3.0, 2.0 / 3.0, 8.0 / 9.0, 1.0};
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j)
      s.control_points.emplace_back(10.0 * greville[i], 10.0 * greville[j], 0.0);
  }
  s.trim_loops.push_back(rectangle_loop(inset, 1.0 - inset, inset, 1.0 - inset));
  TrimCurve hole;
  hole.uv = make_circle(Vec3(0.45, 0.55, 0.0), 0.2);
  hole.uv.dimension = 2;
  NurbsCurve edge = hole.uv;
  edge.dimension = 3;
  for (Vec3& c : edge.control_points)
    c *= 10.0;  // S is linear: the edge is the uv circle scaled, same weights and parameter
  hole.edge = edge;
  s.trim_loops.push_back({{hole}});
  return s;
}

// Closed form: the nearest point of the planar face to p.
double flat_panel_distance(const Vec3& p, double inset = 0.05) {
  const double lo = 10.0 * inset, hi = 10.0 - 10.0 * inset;
  const Vec2 q(p.x(), p.y());
  double planar = 0.0;
  const double r = (q - kHoleCentre).norm();
  if (r < kHoleRadius) {
    planar = kHoleRadius - r;  // to the rim (the disc is well inside the square)
  } else {
    const Vec2 c(std::clamp(q.x(), lo, hi), std::clamp(q.y(), lo, hi));
    planar = (q - c).norm();  // the clamped point is outside the disc (it is far from the border)
  }
  return std::sqrt(p.z() * p.z() + planar * planar);
}

std::vector<Vec3> flat_panel_points() {
  std::mt19937_64 rng(7001);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> pts;
  for (int k = 0; k < 300; ++k)
    pts.emplace_back(-2.0 + 14.0 * unit(rng), -2.0 + 14.0 * unit(rng), -3.0 + 6.0 * unit(rng));
  // Over the hole: the untrimmed foot is in the hole.
  for (int k = 0; k < 150; ++k) {
    const double a = 2.0 * kPi * unit(rng), r = kHoleRadius * std::sqrt(unit(rng));
    pts.emplace_back(kHoleCentre.x() + r * std::cos(a), kHoleCentre.y() + r * std::sin(a),
                     -2.0 + 4.0 * unit(rng));
  }
  // The hole's centre: every rim point is equidistant.
  for (double z : {-1.0, -1e-3, 0.0, 1e-9, 0.5, 3.0})
    pts.emplace_back(kHoleCentre.x(), kHoleCentre.y(), z);
  // Just inside and outside the rim, near the plane.
  for (int k = 0; k < 80; ++k) {
    const double a = 2.0 * kPi * unit(rng);
    const double r =
        kHoleRadius + (k % 2 == 0 ? 1.0 : -1.0) * std::pow(10.0, -1.0 - 6.0 * unit(rng));
    pts.emplace_back(kHoleCentre.x() + r * std::cos(a), kHoleCentre.y() + r * std::sin(a),
                     (unit(rng) - 0.5) * 1e-2);
  }
  // Around the square's corners and sides, above and beside.
  for (double x :
       {kSquareLo - 0.3, kSquareLo, kSquareLo + 1e-7, kSquareHi - 0.2, kSquareHi + 0.4}) {
    for (double y : {kSquareLo - 1e-6, kSquareLo + 0.1, 5.0, kSquareHi, kSquareHi + 2.0}) {
      for (double z : {0.0, 0.7, -2.0})
        pts.emplace_back(x, y, z);
    }
  }
  return pts;
}

Model single(const NurbsSurface& s) {
  Model m;
  m.surfaces.push_back(s);
  return m;
}

double diagonal(const PreparedModel& m) {
  return (m.bounds().hi - m.bounds().lo).norm();
}

void check_flat_panel(double inset) {
  const double lo = 10.0 * inset, hi = 10.0 - 10.0 * inset;
  const PreparedModel model(single(flat_panel(inset)));
  const std::vector<Vec3> pts = flat_panel_points();
  Projector projector(model);
  ProjectionResults out;
  projector.project_serial(PointView::of(pts), {}, out);
  const double tol = 1e-9 * diagonal(model);
  const NurbsSurface& s = model.model().surfaces[0];
  int failures = 0, edge_feet = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    ASSERT_EQ(out.status[i], ProjectionStatus::ok) << i;
    const double exact = flat_panel_distance(pts[i], inset);
    // Both directions at once: not farther than the true distance (nothing missed) and not
    // closer (no point of the hole or of the cut-away border counted).
    const bool ok = std::abs(out.distance[i] - exact) <= tol;
    failures += !ok;
    EXPECT_TRUE(ok) << "point " << i << " (" << pts[i].transpose() << "): got " << out.distance[i]
                    << ", exact " << exact;
    // The foot is a face point at the reported distance, and (u, v) is its parameter.
    const Vec3& f = out.foot[i];
    EXPECT_NEAR((f - pts[i]).norm(), out.distance[i], tol);
    EXPECT_NEAR(f.z(), 0.0, tol);
    EXPECT_GE((Vec2(f.x(), f.y()) - kHoleCentre).norm(), kHoleRadius - tol) << i;
    EXPECT_GE(std::min(f.x(), f.y()), lo - tol) << i;
    EXPECT_LE(std::max(f.x(), f.y()), hi + tol) << i;
    EXPECT_LE((s.evaluate(out.u[i], out.v[i]) - f).norm(), 1e-8 * diagonal(model)) << i;
    const bool on_rim = std::abs((Vec2(f.x(), f.y()) - kHoleCentre).norm() - kHoleRadius) < 1e-6;
    edge_feet += on_rim;
    // A foot strictly inside the face is no trim-edge foot; a rim foot off the plane's normal
    // (the point is over the hole) can only come from the edge.
    const bool interior =
        !on_rim && std::min(f.x(), f.y()) > lo + 1e-6 && std::max(f.x(), f.y()) < hi - 1e-6;
    if (interior) {
      EXPECT_EQ(out.on_trim_edge[i], 0) << i;
    }
    if (on_rim && std::abs(pts[i].z()) < 0.5 * out.distance[i]) {
      EXPECT_EQ(out.on_trim_edge[i], 1) << i;
    }
    // The plane's normal, up to the side.
    EXPECT_NEAR(std::abs(out.normal[i].z()), 1.0, 1e-9) << i;
  }
  EXPECT_EQ(failures, 0);
  EXPECT_GT(edge_feet, 150);  // the hole's rim was really exercised
}

TEST(TrimmedProjection, FlatPanelWithCircularHoleMatchesClosedForm) {
  check_flat_panel(0.05);
}

TEST(TrimmedProjection, OuterLoopOnTheDomainBorderMatchesClosedForm) {
  check_flat_panel(0.0);
}

TEST(TrimmedProjection, TrimmingPrunesOutsidePatchesAndAddsEdgePieces) {
  const PreparedModel model(single(flat_panel()));
  std::size_t outside = 0, inside = 0, boundary = 0;
  for (std::size_t i = 0; i < model.patch_count(); ++i) {
    switch (model.patch_class(i)) {
      case RegionClass::outside:
        ++outside;
        break;
      case RegionClass::inside:
        ++inside;
        break;
      case RegionClass::boundary:
        ++boundary;
        break;
    }
  }
  EXPECT_EQ(model.patch_count(), 9u);
  EXPECT_EQ(model.hierarchy_patch_items(), inside + boundary);
  EXPECT_GT(boundary, 0u);
  EXPECT_GT(model.edge_piece_count(), 0u);
  for (std::size_t e = 0; e < model.edge_piece_count(); ++e)
    EXPECT_EQ(model.edge_piece_info(e).surface, 0);
  // An untrimmed model: the items are exactly the patches, no edges.
  NurbsSurface plain = flat_panel();
  plain.trim_loops.clear();
  const PreparedModel untrimmed(single(plain));
  EXPECT_EQ(untrimmed.hierarchy_patch_items(), untrimmed.patch_count());
  EXPECT_EQ(untrimmed.edge_piece_count(), 0u);
  for (std::uint32_t k = 0; k < untrimmed.patch_count(); ++k)
    EXPECT_EQ(untrimmed.item_patch(k), k);
}

TEST(TrimmedProjection, ReversedFaceFlipsNormalAndSignedDistance) {
  NurbsSurface s = flat_panel();
  const PreparedModel forward(single(s));
  s.reversed = true;
  const PreparedModel backward(single(s));
  const std::vector<Vec3> pts = flat_panel_points();
  ProjectionResults a, b;
  Projector(forward).project_serial(PointView::of(pts), {}, a);
  Projector(backward).project_serial(PointView::of(pts), {}, b);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_EQ(a.distance[i], b.distance[i]);
    EXPECT_EQ(a.u[i], b.u[i]);
    EXPECT_EQ(a.v[i], b.v[i]);
    EXPECT_EQ(a.normal[i], Vec3(-b.normal[i]));
    // The side is defined where p - foot has a normal component (not for a point beside an
    // edge in the face's plane: (p - foot) . n == 0 there, both report +distance).
    if (std::abs(pts[i].z()) > 0.0) {
      EXPECT_EQ(a.signed_distance[i], -b.signed_distance[i]) << i;
      EXPECT_EQ(a.signed_distance[i] > 0.0, pts[i].z() * a.normal[i].z() > 0.0) << i;
    }
  }
  // Untrimmed surfaces too: the sphere's outer side turned inwards.
  NurbsSurface sphere = make_sphere(Vec3::Zero(), 2.0);
  const PreparedModel out_model(single(sphere));
  sphere.reversed = true;
  const PreparedModel in_model(single(sphere));
  const std::vector<Vec3> probes = {Vec3(3, 0.2, 0.1), Vec3(0.5, 0.3, -0.2)};
  ProjectionResults c, d;
  Projector(out_model).project_serial(PointView::of(probes), {}, c);
  Projector(in_model).project_serial(PointView::of(probes), {}, d);
  for (std::size_t i = 0; i < probes.size(); ++i) {
    EXPECT_EQ(c.normal[i], Vec3(-d.normal[i]));
    EXPECT_EQ(c.signed_distance[i], -d.signed_distance[i]);
  }
}

TEST(TrimmedProjection, WarmHintsThreadsAndMaxDistanceGiveTheColdAnswer) {
  const PreparedModel model(single(flat_panel()));
  const std::vector<Vec3> pts = flat_panel_points();
  Projector projector(model);
  ProjectionResults cold;
  projector.project_serial(PointView::of(pts), {}, cold);
  const double tol = 1e-9 * diagonal(model);
  // Hints: the feet of slightly moved points (an ICP iteration), and deliberately bad ones in
  // the hole, on another part of the face, and out of the domain.
  std::mt19937_64 rng(7002);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::vector<Vec3> moved;
  for (const Vec3& p : pts)
    moved.push_back(p + 0.05 * Vec3(gauss(rng), gauss(rng), gauss(rng)));
  ProjectionResults previous;
  projector.project_serial(PointView::of(moved), {}, previous);
  std::vector<ProjectionHint> hints;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    switch (i % 4) {
      case 0:
        hints.push_back(previous.hint(i));
        break;
      case 1:
        hints.push_back({0, 0.45, 0.55});
        break;  // the hole's centre
      case 2:
        hints.push_back({0, 0.9, 0.1});
        break;
      default:
        hints.push_back({0, -3.0, 7.0});
        break;  // clamped into the cut-away border
    }
  }
  ProjectionResults warm;
  projector.project_serial(PointView::of(pts), {}, warm, hints);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_NEAR(warm.distance[i], cold.distance[i], tol) << i;
    EXPECT_NEAR(warm.distance[i], flat_panel_distance(pts[i]), tol) << i;
  }
  // 1 and 2 threads: identical.
  ProjectionResults one, two;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    ProjectionOptions o;
    o.grain = 16;
    projector.project(PointView::of(pts), o, one, hints);
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    ProjectionOptions o;
    o.grain = 16;
    projector.project(PointView::of(pts), o, two, hints);
  }
  EXPECT_EQ(one.distance, two.distance);
  EXPECT_EQ(one.u, two.u);
  EXPECT_EQ(one.v, two.v);
  EXPECT_EQ(one.foot, two.foot);
  EXPECT_EQ(one.distance, warm.distance);
  // max_distance: points within it get the exact answer, the others none.
  ProjectionOptions limited;
  limited.max_distance = 1.5;
  ProjectionResults capped;
  projector.project_serial(PointView::of(pts), limited, capped, hints);
  int within = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double exact = flat_panel_distance(pts[i]);
    if (exact < limited.max_distance - tol) {
      ++within;
      ASSERT_EQ(capped.status[i], ProjectionStatus::ok) << i;
      EXPECT_NEAR(capped.distance[i], exact, tol) << i;
    } else if (exact > limited.max_distance + tol) {
      EXPECT_EQ(capped.status[i], ProjectionStatus::beyond_max_distance) << i;
    }
  }
  EXPECT_GT(within, 100);
}

// A foot at a trim loop's vertex is an edge foot: points in the outward cone of a star face's
// tips have the tip as their closest point, off the plane's normal. The trimmed clipping may
// offer the tip itself (a corner of a box or a box-constrained Newton lands on it, in the
// region), and the edge pieces then tie with it; the answer must still say "trim edge", cold
// and from the hints of slightly moved points (ICP's next pass), or ICP would fit the point to
// the plane through the tip (model_finder's beyond_edge trusts the flag). A foot inside the
// face stays a surface foot.
TEST(TrimmedProjection, FeetAtATrimLoopsVertexAreTrimEdgeFeet) {
  NurbsSurface s = flat_panel();
  s.trim_loops.clear();
  const Vec2 centre(0.5, 0.5);
  constexpr int kTips = 7;
  constexpr double kPhase = 0.3, kOuter = 0.4, kInner = 0.15;
  s.trim_loops.push_back(star_loop(centre, kInner, kOuter, kTips, kPhase));
  const PreparedModel model(single(s));
  // Points on each tip's bisector outwards, at heights above and below the plane; and points
  // over the face's core, whose feet are inside.
  std::vector<Vec3> pts;
  std::vector<Vec3> tips;
  for (int k = 0; k < kTips; ++k) {
    const double a = kPhase + 2.0 * kPi * k / kTips;
    const Vec2 dir(std::cos(a), std::sin(a));
    const Vec2 tip = 10.0 * (centre + kOuter * dir);
    for (double r : {0.01, 0.3, 1.0, 2.5}) {
      for (double z : {-2.0, -0.1, 0.0, 0.05, 1.0, 4.0}) {
        pts.emplace_back(tip.x() + r * dir.x(), tip.y() + r * dir.y(), z);
        tips.emplace_back(tip.x(), tip.y(), 0.0);
      }
    }
  }
  const std::size_t at_tips = pts.size();
  for (double z : {-1.0, 0.3, 2.0}) {
    for (double x : {4.2, 5.0, 5.8})
      pts.emplace_back(x, 5.0, z);
  }
  std::mt19937_64 rng(7003);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::vector<Vec3> moved;
  for (const Vec3& p : pts)
    moved.push_back(p + 0.02 * Vec3(gauss(rng), gauss(rng), gauss(rng)));
  Projector projector(model);
  ProjectionOptions options;
  options.certify = true;
  ProjectionResults cold, previous, warm;
  projector.project_serial(PointView::of(pts), options, cold);
  projector.project_serial(PointView::of(moved), options, previous);
  std::vector<ProjectionHint> hints;
  for (std::size_t i = 0; i < pts.size(); ++i)
    hints.push_back(previous.hint(i));
  projector.project_serial(PointView::of(pts), options, warm, hints);
  const double tol = 1e-9 * diagonal(model);
  for (const ProjectionResults* out : {&cold, &warm}) {
    const char* which = out == &cold ? "cold" : "warm";
    for (std::size_t i = 0; i < pts.size(); ++i) {
      ASSERT_EQ(out->status[i], ProjectionStatus::ok) << which << " " << i;
      if (i < at_tips) {
        EXPECT_NEAR(out->distance[i], (pts[i] - tips[i]).norm(), tol) << which << " " << i;
        EXPECT_NEAR((out->foot[i] - tips[i]).norm(), 0.0, 1e-6) << which << " " << i;
        EXPECT_EQ(out->on_trim_edge[i], 1) << which << " point " << i << " " << pts[i].transpose();
      } else {
        EXPECT_NEAR(out->distance[i], std::abs(pts[i].z()), tol) << which << " " << i;
        EXPECT_EQ(out->on_trim_edge[i], 0) << which << " " << i;
      }
    }
  }
}

// Seed 001's Theorem 2 (the boundary-row reduction) must not be used in a box that straddles a
// loop: a single cubic patch S(u, v) = (10u, 10v, h(u)) and points p with F(0, v) below every
// Bézier coefficient of F (so Theorem 2 hands the whole patch to its edge u = 0), while along u
// F rises to a hump and falls again to a local minimum at u ~ 0.645. The face is u >= 0.25: the
// edge u = 0 is cut away, the hump separates the loop u = 0.25 from the interior minimum, which
// is the answer (it is 6.8 below the loop's squared distance). Reference: F(u, v) = A(u) +
// (10v - p_y)^2 with the v term zero inside the face, so the answer is min A over [0.25, 0.98],
// found by dense sampling and golden section on A alone.
TEST(TrimmedProjection, InteriorMinimumBehindAHumpIsNotLostToACutAwayEdge) {
  const double z[4] = {7.355621288699869, 9.475504723193833, 4.080462846601428,
                       0.17747492155780975};
  const double px = -1.5306911543737831, pz = -2.4406233131278388;
  NurbsSurface s;
  s.degree_u = s.degree_v = 3;
  s.count_u = s.count_v = 4;
  s.knots_u = s.knots_v = {0, 0, 0, 0, 1, 1, 1, 1};
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j)
      s.control_points.emplace_back(10.0 * i / 3.0, 10.0 * j / 3.0, z[i]);
  }
  // The face u >= 0.25 (within a margin) with a corner cut far from the answers: a plain rectangle
  // would be projected as that rectangle of the surface, untrimmed (PreparedModel::
  // rectangle_face), which is checked too, but the straddling boxes are the point here.
  const TrimLoop cut =
      polygon_loop({{0.25, 0.02}, {0.98, 0.02}, {0.98, 0.98}, {0.3, 0.98}, {0.25, 0.93}});
  s.trim_loops.push_back(cut);
  auto squared_distance_u = [&](double u) {
    const Vec3 x = s.evaluate(u, 0.5);
    return (x.x() - px) * (x.x() - px) + (x.z() - pz) * (x.z() - pz);
  };
  double best_u = 0.25, best = squared_distance_u(0.25);
  for (int k = 0; k <= 7300; ++k) {
    const double u = 0.25 + 0.73 * k / 7300.0;
    if (squared_distance_u(u) < best) best = squared_distance_u(u), best_u = u;
  }
  double a = std::max(0.25, best_u - 1e-4), b = std::min(0.98, best_u + 1e-4);
  // Ternary search on the unimodal bracket.
  for (int it = 0; it < 100; ++it) {
    const double m1 = a + (b - a) / 3.0, m2 = b - (b - a) / 3.0;
    if (squared_distance_u(m1) < squared_distance_u(m2)) {
      b = m2;
    } else {
      a = m1;
    }
  }
  best = std::min(best, squared_distance_u(0.5 * (a + b)));
  ASSERT_GT(best_u, 0.5);  // the interior minimum, not the loop u = 0.25
  ASSERT_LT(best + 5.0, squared_distance_u(0.25));
  std::vector<Vec3> pts;
  for (double py : {2.5, 3.7, 5.0, 6.1, 7.9})
    pts.emplace_back(px, py, pz);
  for (const bool rectangle : {false, true}) {
    s.trim_loops = {rectangle ? rectangle_loop(0.25, 0.98, 0.02, 0.98) : cut};
    const PreparedModel model(single(s));
    ASSERT_EQ(model.rectangle_face(0), rectangle);
    ProjectionResults out;
    Projector(model).project_serial(PointView::of(pts), {}, out);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      EXPECT_NEAR(out.distance[i], std::sqrt(best), 1e-9 * diagonal(model)) << rectangle << i;
      EXPECT_NEAR(out.u[i], 0.5 * (a + b), 1e-6) << rectangle << i;
      EXPECT_NEAR(out.v[i], pts[i].y() / 10.0, 1e-9) << rectangle << i;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Brute-force reference for any trimmed surface.

class BruteForce {
 public:
  BruteForce(const NurbsSurface& s, int grid) : s_(s), region_(s), edges_(trim_edges(s)) {
    const ParamInterval du = s.domain_u(), dv = s.domain_v();
    hu_ = du.width() / grid;
    hv_ = dv.width() / grid;
    for (int i = 0; i <= grid; ++i) {
      for (int j = 0; j <= grid; ++j) {
        const double u = du.to_parent(double(i) / grid), v = dv.to_parent(double(j) / grid);
        if (!region_.contains(u, v)) continue;
        uv_.emplace_back(u, v);
        xyz_.push_back(s.evaluate(u, v));
      }
    }
    for (const TrimEdge& e : edges_) {
      EdgeSamples es;
      const ParamInterval d = e.edge.domain();
      const int n = 3000;
      for (int k = 0; k <= n; ++k) {
        es.t.push_back(d.to_parent(double(k) / n));
        es.x.push_back(e.edge.evaluate(es.t.back()));
      }
      samples_.push_back(std::move(es));
    }
  }

  // Squared distance from p to the face.
  double distance_sq(const Vec3& p) const { return std::min(interior(p), edges(p)); }
  // Squared distance from p to the edges only (also: is a foot on an edge?).
  double edges(const Vec3& p) const {
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      const EdgeSamples& es = samples_[e];
      // The best few samples (one per neighbourhood), each refined by golden section.
      std::vector<std::pair<double, int>> order;
      for (std::size_t k = 0; k < es.x.size(); ++k)
        order.push_back({(es.x[k] - p).squaredNorm(), int(k)});
      std::sort(order.begin(), order.end());
      std::vector<int> chosen;
      for (const auto& [d, k] : order) {
        if (chosen.size() >= 3) break;
        bool near = false;
        for (int c : chosen)
          near |= std::abs(c - k) < 20;
        if (!near) chosen.push_back(k);
      }
      for (int k : chosen) {
        double a = es.t[std::max(k - 1, 0)],
               b = es.t[std::min<std::size_t>(k + 1, es.t.size() - 1)];
        auto f = [&](double t) { return (edges_[e].edge.evaluate(t) - p).squaredNorm(); };
        best = std::min({best, test::golden_section_minimum(f, a, b, 90), f(es.t[k])});
      }
    }
    return best;
  }
  // Squared distance from p to the interior critical points (polished grid samples).
  double interior(const Vec3& p) const {
    std::vector<std::pair<double, int>> order;
    order.reserve(xyz_.size());
    for (std::size_t k = 0; k < xyz_.size(); ++k)
      order.push_back({(xyz_[k] - p).squaredNorm(), int(k)});
    const std::size_t keep = std::min<std::size_t>(400, order.size());
    std::partial_sort(order.begin(), order.begin() + keep, order.end());
    std::vector<Vec2> chosen;
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < keep && chosen.size() < 6; ++k) {
      const Vec2 uv = uv_[order[k].second];
      bool near = false;
      for (const Vec2& c : chosen)
        near |= std::abs(c.x() - uv.x()) < 4 * hu_ && std::abs(c.y() - uv.y()) < 4 * hv_;
      if (near) continue;
      chosen.push_back(uv);
      best = std::min(best, polish(p, uv));
    }
    return best;
  }
  bool contains(double u, double v) const { return region_.contains(u, v); }

 private:
  // Descent (Newton where the Hessian is positive definite, else gradient) that only accepts
  // steps decreasing F and staying in the region: ends at an interior critical point or near a
  // loop (which the edges cover).
  double polish(const Vec3& p, Vec2 uv) const {
    auto F = [&](const Vec2& x) { return (s_.evaluate(x.x(), x.y()) - p).squaredNorm(); };
    double f = F(uv);
    for (int it = 0; it < 40; ++it) {
      const SurfaceDerivatives d = s_.derivatives(uv.x(), uv.y());
      const Vec3 r = d.s - p;
      const Vec2 g(r.dot(d.su), r.dot(d.sv));
      Eigen::Matrix2d h;
      h << d.su.dot(d.su) + r.dot(d.suu), d.su.dot(d.sv) + r.dot(d.suv),
          d.su.dot(d.sv) + r.dot(d.suv), d.sv.dot(d.sv) + r.dot(d.svv);
      Vec2 step;
      if (h(0, 0) > 0 && h.determinant() > 1e-14 * h.squaredNorm()) {
        step = -h.inverse() * g;
      } else {
        step = -g / (d.su.squaredNorm() + d.sv.squaredNorm() + 1e-300);
      }
      bool moved = false;
      for (double a = 1.0; a > 1e-12; a *= 0.5) {
        const Vec2 x = uv + a * step;
        if (x.x() < s_.domain_u().lo || x.x() > s_.domain_u().hi || x.y() < s_.domain_v().lo ||
            x.y() > s_.domain_v().hi || !region_.contains(x.x(), x.y()))
          continue;
        const double fx = F(x);
        if (fx < f) {
          moved = (x - uv).norm() > 1e-15;
          uv = x;
          f = fx;
          break;
        }
      }
      if (!moved) break;
    }
    return f;
  }

  struct EdgeSamples {
    std::vector<double> t;
    std::vector<Vec3> x;
  };
  const NurbsSurface& s_;
  TrimRegion region_;
  std::vector<TrimEdge> edges_;
  std::vector<EdgeSamples> samples_;
  std::vector<Vec2> uv_;
  std::vector<Vec3> xyz_;
  double hu_ = 0, hv_ = 0;
};

// Projects `pts` onto the one-surface model and checks both directions against the reference.
void check_against_brute_force(const NurbsSurface& surface, const std::vector<Vec3>& pts,
                               int grid) {
  const PreparedModel model(single(surface));
  // The face as given (the prepared model may hold it in another form: PreparedModel::
  // rectangle_face).
  const NurbsSurface& s = surface;
  BruteForce reference(s, grid);
  Projector projector(model);
  ProjectionResults out;
  projector.project_serial(PointView::of(pts), {}, out);
  const double diag = diagonal(model);
  const double tol = 1e-9 * diag;
  int failures = 0, edge_feet = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    ASSERT_EQ(out.status[i], ProjectionStatus::ok) << i;
    const double ref = std::sqrt(reference.distance_sq(pts[i]));
    // Not worse than the reference (nothing missed).
    const bool not_worse = out.distance[i] <= ref + tol;
    // Not better by cheating: the foot is at the reported distance, is S(u, v), and is a face
    // point: on an edge, or (u, v) inside the region.
    const Vec3& f = out.foot[i];
    const bool on_edge = reference.edges(f) <= tol * tol;
    edge_feet += on_edge;
    const bool in_face = on_edge || reference.contains(out.u[i], out.v[i]);
    const bool consistent = std::abs((f - pts[i]).norm() - out.distance[i]) <= tol &&
                            (s.evaluate(out.u[i], out.v[i]) - f).norm() <= 1e-8 * diag;
    const bool not_better = out.distance[i] >= ref - tol;
    const bool ok = not_worse && in_face && consistent && not_better;
    failures += !ok;
    EXPECT_TRUE(ok) << "point " << i << " (" << pts[i].transpose() << "): got " << out.distance[i]
                    << " at (" << out.u[i] << ", " << out.v[i] << "), reference " << ref
                    << "; on edge " << on_edge << ", in face " << in_face << ", consistent "
                    << consistent;
  }
  EXPECT_EQ(failures, 0);
  // Both kinds of feet were exercised: on edges and inside the face.
  EXPECT_GT(edge_feet, 0);
  EXPECT_LT(edge_feet, static_cast<int>(pts.size()) * 9 / 10);
  // Warm hints (the cold answers, and those of other points) give the same distances.
  std::vector<ProjectionHint> hints;
  for (std::size_t i = 0; i < pts.size(); ++i)
    hints.push_back(out.hint((i * 7 + 3) % pts.size()));
  ProjectionResults warm;
  projector.project_serial(PointView::of(pts), {}, warm, hints);
  for (std::size_t i = 0; i < pts.size(); ++i)
    EXPECT_NEAR(warm.distance[i], out.distance[i], tol) << i;
}

std::vector<Vec3> box_points(const Aabb& box, int count, std::uint64_t seed, double pad) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Vec3 size = box.hi - box.lo;
  std::vector<Vec3> pts;
  for (int k = 0; k < count; ++k) {
    pts.push_back(box.lo - pad * size +
                  Vec3(unit(rng), unit(rng), unit(rng)).cwiseProduct((1.0 + 2.0 * pad) * size));
  }
  return pts;
}

// Points near the face: samples of the UNTRIMMED surface (many over holes and cut-away parts)
// moved along the normal.
std::vector<Vec3> near_points(const NurbsSurface& s, int count, std::uint64_t seed, double reach) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> pts;
  for (int k = 0; k < count; ++k) {
    const double u = s.domain_u().to_parent(unit(rng)), v = s.domain_v().to_parent(unit(rng));
    pts.push_back(s.evaluate(u, v) + reach * (2.0 * unit(rng) - 1.0) * surface_normal(s, u, v));
  }
  return pts;
}

Aabb control_box(const NurbsSurface& s) {
  Aabb box;
  for (const Vec3& c : s.control_points)
    box.extend(c);
  return box;
}

TEST(TrimmedProjection, SphereWindowMatchesBruteForce) {
  NurbsSurface s = make_sphere(Vec3(1.0, -2.0, 0.5), 5.0);
  s.trim_loops.push_back(rectangle_loop(0.15, 0.6, 0.08, 0.47));
  s.trim_loops.push_back(polygon_loop({{0.3, 0.2}, {0.45, 0.25}, {0.35, 0.35}}));
  std::vector<Vec3> pts = box_points(control_box(s), 120, 7101, 0.3);
  for (const Vec3& p : near_points(s, 120, 7102, 1.0))
    pts.push_back(p);
  // The centre: every sphere point is at distance 5 (equidistant); the answer must be 5 too.
  pts.push_back(Vec3(1.0, -2.0, 0.5));
  check_against_brute_force(s, pts, 300);
  const PreparedModel model(single(s));
  ProjectionResults out;
  Projector(model).project_serial(PointView::of(std::span<const Vec3>(&pts.back(), 1)), {}, out);
  EXPECT_NEAR(out.distance[0], 5.0, 1e-12 * 5.0);
}

TEST(TrimmedProjection, FreeformPanelWithStarHoleMatchesBruteForce) {
  NurbsSurface s = test::random_surface(7201, 3, 3, 8, 8, false);
  const ParamInterval du = s.domain_u(), dv = s.domain_v();
  auto at = [&](double a, double b) { return Vec2(du.to_parent(a), dv.to_parent(b)); };
  s.trim_loops.push_back(
      polygon_loop({at(0.04, 0.06), at(0.95, 0.03), at(0.97, 0.96), at(0.05, 0.93)}));
  const Vec2 c = at(0.5, 0.45);
  s.trim_loops.push_back(star_loop(c, 0.12 * du.width(), 0.3 * du.width(), 5, 0.3));
  std::vector<Vec3> pts = box_points(control_box(s), 150, 7202, 0.2);
  for (const Vec3& p : near_points(s, 200, 7203, 0.8))
    pts.push_back(p);
  check_against_brute_force(s, pts, 300);
}

TEST(TrimmedProjection, ExamplesPanelWithStarHoleMatchesBruteForce) {
  NurbsSurface s = test::read_example_surface("panel.json");
  ASSERT_FALSE(s.validate().has_value());
  const ParamInterval du = s.domain_u(), dv = s.domain_v();
  auto at = [&](double a, double b) { return Vec2(du.to_parent(a), dv.to_parent(b)); };
  s.trim_loops.push_back(
      polygon_loop({at(0.03, 0.05), at(0.96, 0.02), at(0.98, 0.97), at(0.02, 0.95)}));
  s.trim_loops.push_back(star_loop(at(0.47, 0.52), 0.1 * du.width(), 0.33 * du.width(), 6, 0.2));
  std::vector<Vec3> pts = box_points(control_box(s), 150, 7251, 0.15);
  for (const Vec3& p : near_points(s, 200, 7252, 5.0))
    pts.push_back(p);
  check_against_brute_force(s, pts, 300);
}

// A face that is a rectangle of its domain (PreparedModel::rectangle_face: projected as that
// rectangle of the surface, untrimmed) against the brute force of the trimmed face as given; on
// a polynomial and a rational surface, the rectangle's sides inside knot spans. A foot on its
// border off the normal is a trim-edge foot, as on any trimmed face.
TEST(TrimmedProjection, RectangleFaceMatchesBruteForce) {
  for (const bool rational : {false, true}) {
    NurbsSurface s = test::random_surface(7261, 3, 3, 8, 7, rational);
    const ParamInterval du = s.domain_u(), dv = s.domain_v();
    const double u0 = du.to_parent(0.13), u1 = du.to_parent(0.71);
    const double v0 = dv.to_parent(0.3), v1 = dv.to_parent(0.94);
    s.trim_loops.push_back(rectangle_loop(u0, u1, v0, v1));
    const PreparedModel model(single(s));
    ASSERT_TRUE(model.rectangle_face(0));
    std::vector<Vec3> pts = box_points(control_box(s), 150, 7262, 0.2);
    for (const Vec3& p : near_points(s, 200, 7263, 0.8))
      pts.push_back(p);
    check_against_brute_force(s, pts, 300);
    ProjectionResults out;
    Projector(model).project_serial(PointView::of(pts), {}, out);
    int border = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const Vec3 offset = pts[i] - out.foot[i];
      const bool off_normal = std::abs(offset.dot(out.normal[i])) < 0.99 * out.distance[i];
      const bool inside = out.u[i] > u0 && out.u[i] < u1 && out.v[i] > v0 && out.v[i] < v1;
      if (off_normal) {
        ++border;
        EXPECT_EQ(out.on_trim_edge[i], 1) << rational << " " << i;
      } else if (inside) {
        EXPECT_EQ(out.on_trim_edge[i], 0) << rational << " " << i;
      }
    }
    EXPECT_GT(border, 20);
  }
}

TEST(TrimmedProjection, RationalExtremeWeightsMatchesBruteForce) {
  NurbsSurface s = test::random_surface(7301, 3, 2, 6, 5, true);
  std::mt19937_64 rng(7302);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (double& w : s.weights)
    w = std::exp(-3.5 + 7.0 * unit(rng));  // 0.03 .. 33
  const ParamInterval du = s.domain_u(), dv = s.domain_v();
  auto at = [&](double a, double b) { return Vec2(du.to_parent(a), dv.to_parent(b)); };
  s.trim_loops.push_back(
      polygon_loop({at(0.02, 0.1), at(0.9, 0.02), at(0.98, 0.9), at(0.5, 0.75), at(0.1, 0.97)}));
  s.trim_loops.push_back(star_loop(at(0.45, 0.4), 0.08 * du.width(), 0.2 * du.width(), 4, 0.1));
  std::vector<Vec3> pts = box_points(control_box(s), 150, 7303, 0.2);
  for (const Vec3& p : near_points(s, 200, 7304, 0.5))
    pts.push_back(p);
  check_against_brute_force(s, pts, 300);
}

TEST(TrimmedProjection, TrimmedTorusMatchesBruteForce) {
  NurbsSurface s = make_torus(Vec3(0.0, 0.0, 0.0), 4.0, 1.5);
  // A band across the seam region of u (the tube) and most of the way around the axis, with a
  // triangular hole.
  s.trim_loops.push_back(rectangle_loop(0.1, 0.85, 0.05, 0.7));
  s.trim_loops.push_back(polygon_loop({{0.3, 0.2}, {0.6, 0.3}, {0.4, 0.5}}));
  std::vector<Vec3> pts = box_points(control_box(s), 120, 7401, 0.2);
  for (const Vec3& p : near_points(s, 150, 7402, 1.2))
    pts.push_back(p);
  // On the axis (a whole circle of tube points is equidistant) and on the tube's centre circle.
  for (double z : {-2.0, 0.0, 0.3, 3.0})
    pts.emplace_back(0.0, 0.0, z);
  for (double a : {0.1, 1.0, 2.5, 4.0, 5.5})
    pts.emplace_back(4.0 * std::cos(a), 4.0 * std::sin(a), 0.0);
  check_against_brute_force(s, pts, 300);
}

// Several faces in one hierarchy: two trimmed faces, an untrimmed one and a reversed trimmed
// one. Each point's answer is the best of the faces' answers, each face checked on its own by
// the tests above (here: projected alone in a one-face model), with the right entity.
TEST(TrimmedProjection, MultiFaceModelIsTheBestOfItsFaces) {
  Model model;
  model.surfaces.push_back(flat_panel());
  NurbsSurface sphere = make_sphere(Vec3(5.0, 5.0, 4.0), 3.0);
  sphere.trim_loops.push_back(rectangle_loop(0.1, 0.55, 0.2, 0.9));
  model.surfaces.push_back(sphere);
  model.surfaces.push_back(make_torus(Vec3(5.0, 5.0, -3.0), 3.0, 1.0));
  NurbsSurface freeform = test::random_surface(7501, 3, 3, 6, 6, true);
  for (Vec3& c : freeform.control_points)
    c += Vec3(2.0, 2.0, 6.0);
  const ParamInterval du = freeform.domain_u(), dv = freeform.domain_v();
  freeform.trim_loops.push_back(star_loop(Vec2(du.to_parent(0.5), dv.to_parent(0.5)),
                                          0.2 * du.width(), 0.45 * du.width(), 5, 0.0));
  freeform.reversed = true;
  model.surfaces.push_back(freeform);
  const PreparedModel prepared(model);
  std::vector<Vec3> pts = box_points(prepared.bounds(), 300, 7502, 0.1);
  for (const Vec3& p : flat_panel_points())
    pts.push_back(p);
  Projector projector(prepared);
  ProjectionResults all;
  projector.project_serial(PointView::of(pts), {}, all);
  std::vector<ProjectionResults> alone(model.surfaces.size());
  for (std::size_t f = 0; f < model.surfaces.size(); ++f) {
    const PreparedModel one(single(model.surfaces[f]));
    Projector(one).project_serial(PointView::of(pts), {}, alone[f]);
  }
  const double tol = 1e-9 * diagonal(prepared);
  int failures = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (const ProjectionResults& r : alone)
      best = std::min(best, r.distance[i]);
    ASSERT_EQ(all.status[i], ProjectionStatus::ok);
    const bool ok = std::abs(all.distance[i] - best) <= tol &&
                    std::abs(alone[all.entity[i]].distance[i] - best) <= tol;
    failures += !ok;
    EXPECT_TRUE(ok) << i << ": " << all.distance[i] << " on face " << all.entity[i] << ", best "
                    << best;
  }
  EXPECT_EQ(failures, 0);
  // Every face wins somewhere.
  for (int f = 0; f < 4; ++f)
    EXPECT_NE(std::count(all.entity.begin(), all.entity.end(), f), 0) << f;
}

// The default certificate radius is a share of the model's size as trimmed (issue 26, item 4): a
// face that is a corner of a large plane (a triangle 10 wide cut from a plane 1000 wide) gets
// certificates of at most 1e-3 of its own diagonal, not of the plane's.
TEST(TrimmedProjection, DefaultCertificateRadiusFollowsTheTrimmedFaces) {
  NurbsSurface s;
  s.name = "corner of a large plane";
  s.degree_u = s.degree_v = 1;
  s.knots_u = s.knots_v = {0, 0, 1, 1};
  s.count_u = s.count_v = 2;
  s.control_points = {Vec3(0, 0, 0), Vec3(0, 1000, 0), Vec3(1000, 0, 0), Vec3(1000, 1000, 0)};
  s.trim_loops.push_back(polygon_loop({Vec2(0, 0), Vec2(0.01, 0), Vec2(0, 0.01)}));
  const PreparedModel model(single(s));
  const double size = model.geometry_bounds().box.diagonal();
  ASSERT_NEAR(size, 10.0 * std::sqrt(2.0), 1e-9);
  ASSERT_GT(model.bounds().diagonal(), 1000.0);
  std::vector<Vec3> pts;
  for (double x : {1.0, 2.0, 3.0}) {
    for (double y : {1.0, 2.0, 3.0}) {
      for (double z : {0.5, -1.0})
        pts.emplace_back(x, y, z);
    }
  }
  Projector projector(model);
  ProjectionOptions options;
  options.certify = true;
  ProjectionResults out;
  projector.project_serial(PointView::of(pts), options, out);
  int made = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    ASSERT_EQ(out.status[i], ProjectionStatus::ok) << i;
    EXPECT_NEAR(out.distance[i], std::abs(pts[i].z()), 1e-12) << i;
    const WarmCertificate& c = out.certificate[i];
    if (!(c.radius > 0.0f)) continue;
    ++made;
    EXPECT_LE(c.radius, 1e-3 * size) << i;
  }
  EXPECT_GT(made, 0);
}

// A cold start's seed on a trimmed face is a sample inside the face. Where the seed is the
// answer, its polish (a Newton over the whole patch) must not carry it out of the face. Here the
// face is a pentagon whose edge u = 1.75 runs across patches, through seed samples (s = 0.75),
// and contains() counts those samples in; for the points beyond that edge the closest face point is
// on it (often a sample, which the edge pieces then only tie), while the plane's closest point
// lies outside the face, nearer.
TEST(TrimmedProjection, ASeedOnATrimmedFaceIsNotPolishedOutOfTheFace) {
  NurbsSurface s;
  s.name = "rectangle of a plane of 4 x 4 patches";
  s.degree_u = s.degree_v = 1;
  s.knots_u = s.knots_v = {0, 0, 1, 2, 3, 4, 4};
  s.count_u = s.count_v = 5;
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j)
      s.control_points.emplace_back(i, j, 0);
  }
  // Not a rectangle (that would be projected as an untrimmed face on a smaller domain).
  s.trim_loops.push_back(polygon_loop(
      {Vec2(0.5, 0.5), Vec2(1.75, 0.5), Vec2(1.75, 3), Vec2(0.5, 3), Vec2(0.25, 1.75)}));
  const PreparedModel model(single(s));
  ASSERT_NE(model.surface_region(0), nullptr);
  ASSERT_TRUE(model.surface_region(0)->contains(1.75, 1.5));
  std::vector<Vec3> pts;
  for (double dx : {0.1, 0.3, 0.5, 1.0}) {
    for (double y = 0.75; y < 2.9; y += 0.125) {
      for (double z : {0.05, 0.3, -0.7})
        pts.emplace_back(1.75 + dx, y, z);
    }
  }
  Projector projector(model);
  ProjectionResults out;
  projector.project_serial(PointView::of(pts), ProjectionOptions{}, out);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    ASSERT_EQ(out.status[i], ProjectionStatus::ok) << i;
    EXPECT_NEAR(out.distance[i], std::hypot(pts[i].x() - 1.75, pts[i].z()), 1e-10) << i;
  }
}

}  // namespace
}  // namespace nurbsreg::engine
