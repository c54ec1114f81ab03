// TrimRegion against an independent reference: the even-odd rule on a very fine polyline of the
// loops (uniform parameter samples evaluated with NurbsCurve::evaluate; no Bézier decomposition,
// no monotone pieces), checked only at points farther from the polyline than its chord error
// bound (1/8 h^2 max|C''|, times a safety factor). classify() is checked against contains() on
// random boxes.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
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
  PolylineReference(const NurbsSurface& s, int segments_per_loop) {
    du_ = s.domain_u();
    dv_ = s.domain_v();
    for (const TrimLoop& loop : s.trim_loops) {
      const int per_curve = std::max(1, segments_per_loop / static_cast<int>(loop.curves.size()));
      std::vector<Vec2> poly;
      for (const TrimCurve& tc : loop.curves) {
        const ParamInterval d = tc.uv.domain();
        const double h = d.width() / per_curve;
        double max_second = 0.0;
        for (int k = 0; k <= per_curve; ++k) {
          const double t = d.lo + h * k;
          const Vec3 p = tc.uv.evaluate(t);
          poly.emplace_back(p.x(), p.y());
          if (tc.uv.degree >= 2) {
            // |C''| at this sample and half-way to the next (safety factor below).
            for (double tt : {t, std::min(d.hi, t + 0.5 * h)}) {
              Vec3 der[3];
              tc.uv.derivatives(tt, 2, der);
              max_second = std::max(max_second, der[2].norm());
            }
          }
        }
        chord_error_ = std::max(chord_error_, 4.0 * 0.125 * h * h * max_second);
      }
      // Closing segments are part of the region's definition (gaps closed by straight lines).
      for (std::size_t k = 0; k < poly.size(); ++k)
        segments_.push_back({poly[k], poly[(k + 1) % poly.size()]});
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

  // Call after construction with the margin within which points are "near".
  void index(double margin) {
    margin_ = margin;
    for (std::size_t k = 0; k < segments_.size(); ++k) {
      const auto& sg = segments_[k];
      const Vec2 a = sg.a.cwiseMin(sg.b) - Vec2(margin, margin);
      const Vec2 b = sg.a.cwiseMax(sg.b) + Vec2(margin, margin);
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

  // Is (u, v) farther than the margin from every segment?
  bool clear(double u, double v) const {
    if (u < lo_.x() || u > hi_.x() || v < lo_.y() || v > hi_.y()) return true;
    const Vec2 p(u, v);
    for (int k : cells_[bucket(u, 0) * kBuckets + bucket(v, 1)]) {
      const Vec2 a = segments_[k].a, b = segments_[k].b;
      const Vec2 ab = b - a;
      const double len2 = ab.squaredNorm();
      const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
      if ((a + t * ab - p).norm() <= margin_) return false;
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
  static constexpr int kBuckets = 128;
  struct Segment {
    Vec2 a, b;
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

}  // namespace
}  // namespace nurbsreg::engine
