// TrimRegion against an independent reference: the even-odd rule on a very fine polyline of the
// loops (uniform parameter samples evaluated with NurbsCurve::evaluate; no Bézier decomposition,
// no monotone pieces), checked only at points farther from the polyline than its chord error
// bound (1/8 h^2 max|C''|, times a safety factor). classify() is checked against contains() on
// random boxes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <ctime>
#include <numbers>
#include <random>

#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/engine/trim_region.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::uniform;

// ---------------------------------------------------------------------------------------------
// Building trimmed surfaces

NurbsCurve uv_curve(int degree, const std::vector<Vec2>& points, const std::vector<double>& w = {},
                    double t0 = 0.0, double t1 = 1.0) {
  NurbsCurve c;
  c.degree = degree;
  c.dimension = 2;
  const int n = static_cast<int>(points.size());
  c.knots.assign(degree + 1, t0);
  for (int k = 1; k < n - degree; ++k)
    c.knots.push_back(t0 + (t1 - t0) * k / (n - degree));
  c.knots.insert(c.knots.end(), degree + 1, t1);
  for (const Vec2& p : points)
    c.control_points.emplace_back(p.x(), p.y(), 0.0);
  c.weights = w;
  return c;
}

NurbsCurve uv_line(const Vec2& a, const Vec2& b) {
  return uv_curve(1, {a, b});
}

// A closed polygon loop of degree-1 curves.
TrimLoop polygon_loop(const std::vector<Vec2>& corners) {
  TrimLoop loop;
  for (std::size_t k = 0; k < corners.size(); ++k)
    loop.curves.push_back({uv_line(corners[k], corners[(k + 1) % corners.size()]), std::nullopt});
  return loop;
}

// The exact circle as one rational quadratic curve (4 quarter arcs).
TrimLoop circle_loop(const Vec2& c, double r) {
  NurbsCurve circle = make_circle(Vec3(c.x(), c.y(), 0.0), r);
  circle.dimension = 2;
  TrimLoop loop;
  loop.curves.push_back({circle, std::nullopt});
  return loop;
}

// Planar bilinear surface over [u0, u1] x [v0, v1] (the geometry does not matter for the
// region; the domain does).
NurbsSurface plane(double u0, double u1, double v0, double v1) {
  NurbsSurface s;
  s.degree_u = s.degree_v = 1;
  s.count_u = s.count_v = 2;
  s.knots_u = {u0, u0, u1, u1};
  s.knots_v = {v0, v0, v1, v1};
  s.control_points = {Vec3(u0, v0, 0), Vec3(u0, v1, 0), Vec3(u1, v0, 0), Vec3(u1, v1, 0)};
  return s;
}

// ---------------------------------------------------------------------------------------------
// Reference: even-odd on a fine polyline, with a bucket grid for speed.

class PolylineReference {
 public:
  // Each segment carries its own chord error bound: 1/8 h^2 max|C''| over the segment (|C''|
  // sampled at its ends and middle), times 4 for safety; closing segments are exact.
  PolylineReference(const NurbsSurface& s, int segments_per_loop) {
    du_ = s.domain_u();
    dv_ = s.domain_v();
    for (const TrimLoop& loop : s.trim_loops) {
      const int per_curve = std::max(1, segments_per_loop / static_cast<int>(loop.curves.size()));
      std::vector<Vec2> poly;
      std::vector<double> err;
      for (const TrimCurve& tc : loop.curves) {
        const ParamInterval d = tc.uv.domain();
        const double h = d.width() / per_curve;
        double second_prev = 0.0;
        for (int k = 0; k <= per_curve; ++k) {
          const double t = d.lo + h * k;
          const Vec3 p = tc.uv.evaluate(t);
          poly.emplace_back(p.x(), p.y());
          double second = 0.0, second_mid = 0.0;
          if (tc.uv.degree >= 2) {
            Vec3 der[3];
            tc.uv.derivatives(t, 2, der);
            second = der[2].norm();
            if (k > 0) {
              tc.uv.derivatives(t - 0.5 * h, 2, der);
              second_mid = der[2].norm();
            }
          }
          if (k > 0) {
            err.back() = 4.0 * 0.125 * h * h * std::max({second, second_mid, second_prev});
          }
          err.push_back(0.0);  // the segment starting here (closing segments stay exact)
          second_prev = second;
        }
      }
      for (std::size_t k = 0; k < poly.size(); ++k) {
        segments_.push_back({poly[k], poly[(k + 1) % poly.size()], err[k]});
        chord_error_ = std::max(chord_error_, err[k]);
      }
    }
    lo_ = Vec2(1e300, 1e300);
    hi_ = Vec2(-1e300, -1e300);
    for (const auto& sg : segments_) {
      lo_ = lo_.cwiseMin(sg.a).cwiseMin(sg.b);
      hi_ = hi_.cwiseMax(sg.a).cwiseMax(sg.b);
    }
    const double pad = 1e-9 * (hi_ - lo_).norm() + 1e-300;
    lo_ -= Vec2(pad, pad);
    hi_ += Vec2(pad, pad);
    rows_.assign(kBuckets, {});
    cells_.assign(kBuckets * kBuckets, {});
  }

  // Call after construction: points within a segment's error bound plus `margin` of it are
  // "near" (not checked).
  void index(double margin) {
    margin_ = margin;
    for (std::size_t k = 0; k < segments_.size(); ++k) {
      const auto& sg = segments_[k];
      const double m = margin + sg.err;
      const Vec2 a = sg.a.cwiseMin(sg.b) - Vec2(m, m);
      const Vec2 b = sg.a.cwiseMax(sg.b) + Vec2(m, m);
      const int i0 = bucket(a.x(), 0), i1 = bucket(b.x(), 0);
      const int j0 = bucket(a.y(), 1), j1 = bucket(b.y(), 1);
      for (int j = j0; j <= j1; ++j) {
        rows_[j].push_back(static_cast<int>(k));
        for (int i = i0; i <= i1; ++i)
          cells_[i * kBuckets + j].push_back(static_cast<int>(k));
      }
    }
  }

  double chord_error() const { return chord_error_; }

  // Is (u, v) farther than its error bound plus the margin from every segment?
  bool clear(double u, double v) const {
    if (u < lo_.x() || u > hi_.x() || v < lo_.y() || v > hi_.y()) return true;
    const Vec2 p(u, v);
    for (int k : cells_[bucket(u, 0) * kBuckets + bucket(v, 1)]) {
      const Vec2 a = segments_[k].a, b = segments_[k].b;
      const Vec2 ab = b - a;
      const double len2 = ab.squaredNorm();
      const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
      if ((a + t * ab - p).norm() <= margin_ + segments_[k].err) return false;
    }
    return true;
  }

  bool contains(double u, double v) const {
    if (u < du_.lo || u > du_.hi || v < dv_.lo || v > dv_.hi) return false;
    if (u < lo_.x() || u > hi_.x() || v < lo_.y() || v > hi_.y()) return false;
    bool in = false;
    for (int k : rows_[bucket(v, 1)]) {
      const Vec2 a = segments_[k].a, b = segments_[k].b;
      if ((a.y() <= v) == (b.y() <= v)) continue;
      const double x = a.x() + (v - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (x > u) in = !in;
    }
    return in;
  }

 private:
  static constexpr int kBuckets = 512;
  struct Segment {
    Vec2 a, b;
    double err;
  };
  int bucket(double x, int axis) const {
    const double f = (x - lo_[axis]) / (hi_[axis] - lo_[axis]);
    return std::clamp(static_cast<int>(f * kBuckets), 0, kBuckets - 1);
  }
  ParamInterval du_, dv_;
  std::vector<Segment> segments_;
  Vec2 lo_, hi_;
  double chord_error_ = 0.0, margin_ = 0.0;
  std::vector<std::vector<int>> rows_, cells_;
};

struct Agreement {
  int checked = 0, inside = 0, mismatches = 0;
};

// contains() == reference at `count` random points of the box (plus the extra points), skipping
// points within the reference's margin of the polyline.
Agreement compare(const TrimRegion& region, const PolylineReference& ref, std::mt19937_64& rng,
                  Vec2 lo, Vec2 hi, int count, const std::vector<Vec2>& extra = {}) {
  Agreement a;
  auto check = [&](double u, double v) {
    if (!ref.clear(u, v)) return;
    ++a.checked;
    const bool want = ref.contains(u, v);
    a.inside += want;
    if (region.contains(u, v) != want) {
      if (a.mismatches < 5) ADD_FAILURE() << "contains(" << u << ", " << v << ") != " << want;
      ++a.mismatches;
    }
  };
  for (int k = 0; k < count; ++k)
    check(uniform(rng, lo.x(), hi.x()), uniform(rng, lo.y(), hi.y()));
  for (const Vec2& p : extra)
    check(p.x(), p.y());
  return a;
}

// Whenever classify() proves inside/outside, many sample points of the box agree.
void check_classify(const TrimRegion& region, std::mt19937_64& rng, Vec2 lo, Vec2 hi, int boxes,
                    double max_size, int* proved = nullptr) {
  int proofs = 0;
  for (int b = 0; b < boxes; ++b) {
    const double w = uniform(rng, 0.0, max_size) * (hi.x() - lo.x());
    const double h = uniform(rng, 0.0, max_size) * (hi.y() - lo.y());
    const double u0 = uniform(rng, lo.x(), hi.x() - w), v0 = uniform(rng, lo.y(), hi.y() - h);
    const RegionClass c = region.classify(u0, u0 + w, v0, v0 + h);
    if (c == RegionClass::boundary) continue;
    ++proofs;
    const bool want = c == RegionClass::inside;
    int bad = 0;
    for (int k = 0; k < 64; ++k) {
      // Corners and edges first, then interior points.
      const double su = k < 4 ? (k & 1) : k < 16 ? (k % 3) * 0.5 : uniform(rng, 0, 1);
      const double sv = k < 4 ? (k >> 1) : k < 16 ? ((k / 3) % 2) : uniform(rng, 0, 1);
      bad += region.contains(u0 + su * w, v0 + sv * h) != want;
    }
    EXPECT_EQ(bad, 0) << "box [" << u0 << ", " << u0 + w << "] x [" << v0 << ", " << v0 + h
                      << "] classified " << (want ? "inside" : "outside");
  }
  if (proved) *proved = proofs;
}

// ---------------------------------------------------------------------------------------------

TEST(TrimRegion, RejectsUntrimmedSurfaceAndDefaultIsEmpty) {
  EXPECT_THROW(TrimRegion(plane(0, 1, 0, 1)), std::invalid_argument);
  NurbsSurface s = plane(0, 1, 0, 1);
  s.trim_loops.push_back({});
  EXPECT_THROW(TrimRegion{s}, std::invalid_argument);
  const TrimRegion empty;
  EXPECT_FALSE(empty.contains(0.5, 0.5));
  EXPECT_EQ(empty.classify(0, 1, 0, 1), RegionClass::outside);
  EXPECT_EQ(empty.piece_count(), 0u);
  s.trim_loops[0] = polygon_loop({{0.2, 0.2}, {0.8, 0.2}, {0.5, 0.8}});
  const TrimRegion triangle(s);
  EXPECT_EQ(triangle.classify(0.4, 0.45, 0.3, 0.35), RegionClass::inside);
  EXPECT_EQ(triangle.classify(0.45, 0.4, 0.3, 0.35), RegionClass::outside);  // empty box
  EXPECT_EQ(triangle.classify(std::nan(""), 0.45, 0.3, 0.35), RegionClass::boundary);
  EXPECT_FALSE(triangle.contains(std::nan(""), 0.3));
  EXPECT_TRUE(triangle.contains(0.5, 0.3));
  // Loops entirely outside the domain: the empty region.
  s.trim_loops[0] = polygon_loop({{1.2, 0.2}, {1.8, 0.2}, {1.5, 0.8}});
  const TrimRegion beyond(s);
  EXPECT_FALSE(beyond.contains(1.5, 0.3));
  EXPECT_EQ(beyond.classify(0, 1, 0, 1), RegionClass::outside);
}

// A 9-pointed star with a comb-shaped hole: concave polygon, horizontal and vertical edges,
// query points exactly at vertex heights and on vertex positions' rows.
TEST(TrimRegion, ConcavePolygonsMatchReference) {
  NurbsSurface s = plane(-2, 2, -2, 2);
  std::vector<Vec2> star;
  for (int k = 0; k < 18; ++k) {
    const double a = std::numbers::pi * k / 9.0;
    const double r = k % 2 == 0 ? 1.8 : 0.8;
    star.emplace_back(r * std::cos(a), r * std::sin(a));
  }
  s.trim_loops.push_back(polygon_loop(star));
  // Comb: teeth of vertical and horizontal edges, vertices on shared heights.
  std::vector<Vec2> comb = {{-0.5, -0.3}, {0.5, -0.3}, {0.5, 0.3}};
  for (int t = 4; t >= 0; --t) {
    const double x = -0.5 + 0.2 * t;
    comb.emplace_back(x, 0.3);
    comb.emplace_back(x, -0.1);
    comb.emplace_back(x - 0.1, -0.1);
    comb.emplace_back(x - 0.1, 0.3);
  }
  s.trim_loops.push_back(polygon_loop(comb));
  const TrimRegion region(s);
  PolylineReference ref(s, 1000);
  ref.index(1e-12);
  std::mt19937_64 rng(7);
  std::vector<Vec2> extra;
  for (const auto* loop : {&star, &comb}) {
    for (const Vec2& p : *loop) {
      for (double du : {-0.37, -0.01, 0.013, 0.29})
        extra.emplace_back(p.x() + du, p.y());  // exactly at a vertex's v
    }
  }
  const Agreement a = compare(region, ref, rng, Vec2(-2.2, -2.2), Vec2(2.2, 2.2), 20000, extra);
  EXPECT_EQ(a.mismatches, 0);
  EXPECT_GT(a.inside, a.checked / 5);
  check_classify(region, rng, Vec2(-2, -2), Vec2(2, 2), 3000, 0.2);
}

// The exact circle: contains == |x - c| < r away from the circle.
TEST(TrimRegion, ExactCircleHole) {
  NurbsSurface s = plane(0, 3, 0, 2);
  s.trim_loops.push_back(polygon_loop({{0.1, 0.1}, {2.9, 0.1}, {2.9, 1.9}, {0.1, 1.9}}));
  const Vec2 c(1.3, 0.9);
  const double r = 0.7;
  s.trim_loops.push_back(circle_loop(c, r));
  const TrimRegion region(s);
  std::mt19937_64 rng(11);
  int checked = 0, bad = 0;
  auto check = [&](const Vec2& p) {
    const double d = (p - c).norm();
    if (std::abs(d - r) <= 1e-12 * r) return;
    ++checked;
    const bool in_rect = p.x() > 0.1 && p.x() < 2.9 && p.y() > 0.1 && p.y() < 1.9;
    bad += region.contains(p.x(), p.y()) != (in_rect && d > r);
  };
  for (int k = 0; k < 100000; ++k)
    check(Vec2(uniform(rng, 0.0, 3.0), uniform(rng, 0.0, 2.0)));
  // Points just off the circle (relative distance 1e-11 .. 1e-6), at all angles including the
  // arcs' joints and v extrema.
  for (int k = 0; k < 20000; ++k) {
    const double a = k < 16 ? std::numbers::pi * k / 8 : uniform(rng, 0, 2 * std::numbers::pi);
    const double rel = std::pow(10.0, uniform(rng, -11, -6)) * (k % 2 ? 1 : -1);
    check(c + r * (1 + rel) * Vec2(std::cos(a), std::sin(a)));
  }
  EXPECT_EQ(bad, 0) << "of " << checked;
  check_classify(region, rng, Vec2(0, 0), Vec2(3, 2), 3000, 0.1);
}

// A closed star-shaped B-spline loop: `count` control points at increasing angles with random
// radii, first == last, optional random weights. Degree up to 12.
TrimLoop star_curve_loop(std::uint64_t seed, const Vec2& c, double r0, double r1, int count,
                         int degree, bool rational) {
  std::mt19937_64 rng(seed);
  std::vector<Vec2> pts;
  std::vector<double> w;
  for (int k = 0; k < count; ++k) {
    const double a = 2 * std::numbers::pi * k / count;
    const double r = uniform(rng, r0, r1);
    pts.push_back(c + r * Vec2(std::cos(a), std::sin(a)));
    w.push_back(rational ? std::exp(uniform(rng, -2.3, 2.3)) : 1.0);
  }
  pts.push_back(pts.front());
  w.push_back(w.front());
  TrimLoop loop;
  loop.curves.push_back(
      {uv_curve(degree, pts, rational ? w : std::vector<double>{}), std::nullopt});
  return loop;
}

// A thick spiral: outer and inner Archimedean spirals (cubic B-splines through control points
// on the spirals) joined by two straight segments.
TrimLoop spiral_loop(const Vec2& c) {
  std::vector<Vec2> outer, inner;
  const int n = 60;
  for (int k = 0; k <= n; ++k) {
    const double a = 4 * std::numbers::pi * k / n;
    const double r = 0.15 + 0.12 * a / (2 * std::numbers::pi);
    outer.push_back(c + (r + 0.04) * Vec2(std::cos(a), std::sin(a)));
    inner.push_back(c + r * Vec2(std::cos(a), std::sin(a)));
  }
  std::reverse(inner.begin(), inner.end());
  TrimLoop loop;
  loop.curves.push_back({uv_curve(3, outer), std::nullopt});
  loop.curves.push_back({uv_line(outer.back(), inner.front()), std::nullopt});
  loop.curves.push_back({uv_curve(3, inner, {}, 2.0, 5.0), std::nullopt});
  loop.curves.push_back({uv_line(inner.back(), outer.front()), std::nullopt});
  return loop;
}

// Outer curved star (degree 12, rational) with holes: an exact circle, a degree-7 rational
// star, a spiral; the outer loop reaches beyond the domain on one side.
NurbsSurface curved_face() {
  NurbsSurface s = plane(0, 4, 0, 3);
  s.trim_loops.push_back(star_curve_loop(1, Vec2(2.2, 1.5), 1.2, 2.0, 40, 12, true));
  s.trim_loops.push_back(circle_loop(Vec2(1.2, 1.0), 0.3));
  s.trim_loops.push_back(star_curve_loop(2, Vec2(3.0, 2.1), 0.2, 0.5, 15, 7, true));
  s.trim_loops.push_back(spiral_loop(Vec2(2.3, 1.4)));
  return s;
}

TEST(TrimRegion, CurvedLoopsWithHolesMatchReference) {
  const NurbsSurface s = curved_face();
  const TrimRegion region(s);
  PolylineReference ref(s, 100000);
  ref.index(1e-12);
  std::mt19937_64 rng(3);
  // Points at the exact heights of the curves' knot points (piece ends), left and right.
  std::vector<Vec2> extra;
  for (const TrimLoop& loop : s.trim_loops) {
    for (const TrimCurve& tc : loop.curves) {
      for (double t : tc.uv.knots) {
        const Vec3 p = tc.uv.evaluate(t);
        for (double du : {-0.3, -1e-3, -1e-6, 1e-6, 1e-3, 0.3})
          extra.emplace_back(p.x() + du, p.y());
      }
    }
  }
  const Agreement a = compare(region, ref, rng, Vec2(-0.2, -0.2), Vec2(4.2, 3.2), 200000, extra);
  EXPECT_EQ(a.mismatches, 0) << "of " << a.checked;
  EXPECT_GT(a.checked, 190000);
  EXPECT_GT(a.inside, a.checked / 5);
  int proved = 0;
  check_classify(region, rng, Vec2(0, 0), Vec2(4, 3), 5000, 0.05, &proved);
  EXPECT_GT(proved, 2500);
  std::printf("curved face: %zu monotone pieces, max chord error bound of the reference %.3g\n",
              region.piece_count(), ref.chord_error());
}

// Points very close to the loops (but farther than the reference's margin): near-boundary
// queries go through the exact crossing count.
TEST(TrimRegion, PointsNearCurvedLoops) {
  const NurbsSurface s = curved_face();
  const TrimRegion region(s);
  PolylineReference ref(s, 100000);
  ref.index(1e-12);
  std::mt19937_64 rng(9);
  std::vector<Vec2> near;
  for (const TrimLoop& loop : s.trim_loops) {
    for (const TrimCurve& tc : loop.curves) {
      const ParamInterval d = tc.uv.domain();
      for (int k = 0; k < 3000; ++k) {
        const double t = uniform(rng, d.lo, d.hi);
        Vec3 der[2];
        tc.uv.derivatives(t, 1, der);
        const Vec2 normal = Vec2(-der[1].y(), der[1].x()).normalized();
        const double off = std::pow(10.0, uniform(rng, -7, -3)) * (k % 2 ? 1 : -1);
        near.push_back(Vec2(der[0].x(), der[0].y()) + off * normal);
      }
    }
  }
  const Agreement a = compare(region, ref, rng, Vec2(0, 0), Vec2(4, 3), 0, near);
  EXPECT_EQ(a.mismatches, 0) << "of " << a.checked;
  EXPECT_GT(a.checked, static_cast<int>(near.size()) / 2);
}

// The outer loop is the domain's boundary itself; a second loop crosses the domain's edge (the
// region is its interior intersected with the domain); a third touches the edge at a vertex.
TEST(TrimRegion, LoopsAlongAndAcrossTheDomainBoundary) {
  NurbsSurface s = plane(-1, 2, 0.5, 1.5);
  s.trim_loops.push_back(polygon_loop({{-1, 0.5}, {2, 0.5}, {2, 1.5}, {-1, 1.5}}));
  s.trim_loops.push_back(polygon_loop({{1.5, 0.7}, {2.5, 0.7}, {2.5, 1.3}, {1.5, 1.3}}));
  s.trim_loops.push_back(polygon_loop({{-1, 1.0}, {-0.5, 0.7}, {-0.3, 1.2}}));
  s.trim_loops.push_back(circle_loop(Vec2(0.5, 1.5), 0.2));  // cut by the domain's top edge
  const TrimRegion region(s);
  PolylineReference ref(s, 100000);
  ref.index(1e-12);
  std::mt19937_64 rng(5);
  std::vector<Vec2> extra;
  for (int k = 0; k <= 60; ++k) {
    const double x = -1 + 3.0 * k / 60;
    for (double y : {0.5, 0.7, 1.0, 1.2, 1.3, 1.5})
      extra.emplace_back(x, y);  // on vertex heights and on the domain's edges
  }
  const Agreement a = compare(region, ref, rng, Vec2(-1.5, 0), Vec2(3, 2), 50000, extra);
  EXPECT_EQ(a.mismatches, 0) << "of " << a.checked;
  EXPECT_GT(a.inside, a.checked / 5);
  // Beyond the domain nothing is inside, although the second loop reaches there.
  EXPECT_FALSE(region.contains(2.2, 1.0));
  EXPECT_EQ(region.classify(2.1, 2.4, 0.8, 1.2), RegionClass::outside);
  EXPECT_EQ(region.classify(-1, 2, 0.5, 1.5), RegionClass::boundary);
  check_classify(region, rng, Vec2(-1, 0.5), Vec2(2, 1.5), 3000, 0.1);
}

// CAD faces' outer loops run along the domain's edge a few ulps off it (a degree-3 curve through
// points 1e-15 inside): that band is the loops' tolerance, so boxes along the edge are proven
// inside, not "boundary"; a loop a visible distance inside the edge still makes them boundary.
TEST(TrimRegion, LoopsWithinToleranceOfTheDomainEdge) {
  const double ulps = 1e-15;
  NurbsSurface s = plane(0, 2, 0, 1);
  TrimLoop outer;
  outer.curves.push_back(
      {uv_curve(3, {{ulps, 0}, {1, ulps}, {1.5, 0}, {2 - ulps, ulps}, {2, 0}}), std::nullopt});
  outer.curves.push_back({uv_line({2, 0}, {2 - ulps, 1}), std::nullopt});
  outer.curves.push_back({uv_line({2 - ulps, 1}, {0, 1 - ulps}), std::nullopt});
  outer.curves.push_back({uv_line({0, 1 - ulps}, {ulps, 0}), std::nullopt});
  s.trim_loops.push_back(outer);
  const TrimRegion region(s);
  EXPECT_EQ(region.classify(0, 2, 0, 1), RegionClass::inside);
  EXPECT_EQ(region.classify(0, 0.5, 0, 0.5), RegionClass::inside);
  EXPECT_TRUE(region.contains(1e-3, 1e-3));
  EXPECT_TRUE(region.contains(1.0, 0.5));
  EXPECT_FALSE(region.contains(2.5, 0.5));
  std::mt19937_64 rng(11);
  check_classify(region, rng, Vec2(0, 0), Vec2(2, 1), 2000, 0.3);
  // A hole: boxes meeting it are boundary, the rest along the edge stay inside.
  s.trim_loops.push_back(circle_loop(Vec2(1.5, 0.5), 0.2));
  const TrimRegion holed(s);
  EXPECT_EQ(holed.classify(0, 2, 0, 1), RegionClass::boundary);
  EXPECT_EQ(holed.classify(0, 0.5, 0, 0.5), RegionClass::inside);
  EXPECT_FALSE(holed.contains(1.5, 0.5));
  check_classify(holed, rng, Vec2(0, 0), Vec2(2, 1), 2000, 0.3);
  // The same outer loop 1e-6 inside the edge: a real sliver, so edge boxes are boundary.
  NurbsSurface t = plane(-1e-6, 2 + 1e-6, -1e-6, 1 + 1e-6);
  t.trim_loops.push_back(outer);
  const TrimRegion inset(t);
  EXPECT_EQ(inset.classify(-1e-6, 0.5, -1e-6, 0.5), RegionClass::boundary);
  EXPECT_FALSE(inset.contains(-5e-7, 0.5));
}

// The grid's prefix sums wrap modulo 2^16: a 256 x 256 grid whose every cell is inside (an outer
// loop of 64 pieces along the domain's edge marks no cell) must still classify the whole grid as
// inside, and boxes of almost all of it from the wrapped sums.
TEST(TrimRegion, LargestGridAllInside) {
  NurbsSurface s = plane(0, 1, 0, 1);
  std::vector<Vec2> corners;
  for (int k = 0; k < 16; ++k)
    corners.emplace_back(k / 16.0, 0.0);
  for (int k = 0; k < 16; ++k)
    corners.emplace_back(1.0, k / 16.0);
  for (int k = 0; k < 16; ++k)
    corners.emplace_back(1.0 - k / 16.0, 1.0);
  for (int k = 0; k < 16; ++k)
    corners.emplace_back(0.0, 1.0 - k / 16.0);
  s.trim_loops.push_back(polygon_loop(corners));
  const TrimRegion region(s);
  ASSERT_GE(region.piece_count(), 64u);  // 256 cells per side
  EXPECT_EQ(region.classify(0, 1, 0, 1), RegionClass::inside);
  EXPECT_EQ(region.classify(0, 0.99, 0, 1), RegionClass::inside);
  EXPECT_EQ(region.classify(0.01, 1, 0.01, 1), RegionClass::inside);
  EXPECT_EQ(region.classify(-0.5, 1, 0, 1), RegionClass::boundary);  // partly beyond the loops
  std::mt19937_64 rng(31);
  check_classify(region, rng, Vec2(0, 0), Vec2(1, 1), 2000, 1.0);
  // A hole in the middle: only boxes clear of it stay inside.
  s.trim_loops.push_back(circle_loop(Vec2(0.5, 0.5), 0.1));
  const TrimRegion holed(s);
  EXPECT_EQ(holed.classify(0, 1, 0, 1), RegionClass::boundary);
  EXPECT_EQ(holed.classify(0, 0.99, 0, 1), RegionClass::boundary);
  EXPECT_EQ(holed.classify(0, 0.3, 0, 1), RegionClass::inside);
  EXPECT_FALSE(holed.contains(0.5, 0.5));
  check_classify(holed, rng, Vec2(0, 0), Vec2(1, 1), 2000, 1.0);
}

// Consecutive curves that miss each other by 1e-9 (gaps and overlaps): closed by straight
// pieces, as the reference polyline does.
TEST(TrimRegion, TinyGapsBetweenCurves) {
  NurbsSurface s = plane(0, 1, 0, 1);
  std::mt19937_64 rng(17);
  TrimLoop loop;
  const int n = 12;
  std::vector<Vec2> corners;
  for (int k = 0; k < n; ++k) {
    const double a = 2 * std::numbers::pi * k / n;
    corners.push_back(Vec2(0.5, 0.5) + (k % 2 ? 0.2 : 0.45) * Vec2(std::cos(a), std::sin(a)));
  }
  for (int k = 0; k < n; ++k) {
    const Vec2 a = corners[k] + Vec2(uniform(rng, -1e-9, 1e-9), uniform(rng, -1e-9, 1e-9));
    const Vec2 b = corners[(k + 1) % n];
    // Curved edges: quadratic with a bulge.
    const Vec2 m = 0.5 * (a + b) + 0.05 * Vec2(-(b - a).y(), (b - a).x());
    loop.curves.push_back({uv_curve(2, {a, m, b}), std::nullopt});
  }
  s.trim_loops.push_back(loop);
  const TrimRegion region(s);
  PolylineReference ref(s, 100000);
  ref.index(1e-12);
  std::vector<Vec2> extra;
  for (const Vec2& c : corners) {
    for (double d : {-1e-6, 1e-6, 3e-9, -3e-9})
      extra.push_back(c + Vec2(d, 0.0));
  }
  const Agreement a = compare(region, ref, rng, Vec2(0, 0), Vec2(1, 1), 50000, extra);
  EXPECT_EQ(a.mismatches, 0) << "of " << a.checked;
  check_classify(region, rng, Vec2(0, 0), Vec2(1, 1), 3000, 0.1);
}

// Query points exactly on the grid's cell borders (the grid box is the loop's bounding box
// here, with max(16, min(256, 4 x pieces)) cells per side) and at vertex heights.
TEST(TrimRegion, PointsOnGridCellBorders) {
  NurbsSurface s = plane(0, 1, 0, 1);
  const std::vector<Vec2> zigzag = {{0.1, 0.1}, {0.9, 0.1}, {0.9, 0.9}, {0.7, 0.9},  {0.7, 0.3},
                                    {0.5, 0.3}, {0.5, 0.9}, {0.3, 0.9}, {0.3, 0.55}, {0.1, 0.55}};
  s.trim_loops.push_back(polygon_loop(zigzag));
  const TrimRegion region(s);
  PolylineReference ref(s, 1000);
  ref.index(1e-12);
  const int side = std::clamp(4 * static_cast<int>(region.piece_count()), 16, 256);
  std::vector<Vec2> extra;
  for (int i = 0; i <= side; ++i) {
    for (int j = 0; j <= side; ++j)
      extra.emplace_back(0.1 + 0.8 * i / side, 0.1 + 0.8 * j / side);
  }
  for (const Vec2& p : zigzag) {
    for (int i = 0; i <= side; ++i)
      extra.emplace_back(0.1 + 0.8 * i / side, p.y());
  }
  std::mt19937_64 rng(23);
  const Agreement a = compare(region, ref, rng, Vec2(0, 0), Vec2(1, 1), 10000, extra);
  EXPECT_EQ(a.mismatches, 0) << "of " << a.checked;
  // Boxes whose edges are cell borders.
  int bad = 0, proofs = 0;
  for (int b = 0; b < 2000; ++b) {
    const int i0 = static_cast<int>(rng() % side), j0 = static_cast<int>(rng() % side);
    const int i1 = std::min(side, i0 + 1 + static_cast<int>(rng() % 4));
    const int j1 = std::min(side, j0 + 1 + static_cast<int>(rng() % 4));
    const double u0 = 0.1 + 0.8 * i0 / side, u1 = 0.1 + 0.8 * i1 / side;
    const double v0 = 0.1 + 0.8 * j0 / side, v1 = 0.1 + 0.8 * j1 / side;
    const RegionClass c = region.classify(u0, u1, v0, v1);
    if (c == RegionClass::boundary) continue;
    ++proofs;
    for (double u : {u0, 0.5 * (u0 + u1), u1}) {
      for (double v : {v0, 0.5 * (v0 + v1), v1})
        bad += region.contains(u, v) != (c == RegionClass::inside);
    }
  }
  EXPECT_EQ(bad, 0);
  EXPECT_GT(proofs, 500);
}

// CPU time of this thread (the machine may be shared: wall time would count other jobs).
double thread_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Not a timed assertion: prints the cost of contains() on the curved face.
TEST(TrimRegion, ReportQueryCost) {
  const TrimRegion region(curved_face());
  std::mt19937_64 rng(1);
  std::vector<Vec2> pts(1 << 20);
  for (Vec2& p : pts)
    p = Vec2(uniform(rng, 0, 4), uniform(rng, 0, 3));
  int inside = 0;
  const auto t0 = thread_seconds();
  for (const Vec2& p : pts)
    inside += region.contains(p.x(), p.y());
  const auto t1 = thread_seconds();
  const double ns = 1e9 * (t1 - t0) / pts.size();
  // Points in boundary cells only (answered by the exact crossing count).
  std::vector<Vec2> near;
  for (const Vec2& p : pts) {
    if (region.classify(p.x(), p.x(), p.y(), p.y()) == RegionClass::boundary) near.push_back(p);
  }
  const auto t2 = thread_seconds();
  int near_inside = 0;
  for (int rep = 0; rep < 20; ++rep) {
    for (const Vec2& p : near)
      near_inside += region.contains(p.x(), p.y());
  }
  const auto t3 = thread_seconds();
  const double ns_near = 1e9 * (t3 - t2) / (20.0 * static_cast<double>(near.size()));
  std::printf(
      "contains(): %.1f ns per query on uniform points (%zu pieces, %.1f%% inside, %.1f%% "
      "in boundary cells); %.1f ns per query in boundary cells\n",
      ns, region.piece_count(), 100.0 * inside / pts.size(), 100.0 * near.size() / pts.size(),
      ns_near);
  EXPECT_GT(inside, 0);
  EXPECT_GT(near_inside, 0);
}

}  // namespace
}  // namespace nurbsreg::engine
