#pragma once
// Deterministic random NURBS entities for tests (fixed seeds; std::mt19937_64 is specified
// exactly by the standard, so every platform draws the same numbers).

#include <algorithm>
#include <random>
#include <string>
#include <utility>

#include "nurbsreg/engine/nurbs_curve.hpp"
#include "nurbsreg/engine/nurbs_surface.hpp"

namespace nurbsreg::test {

using engine::NurbsCurve;
using engine::NurbsSurface;
using engine::Vec3;

// One bicubic Bézier patch (a single-span NURBS surface, domain [0, 1]^2) with control point
// (i, j) at point(i, j), i along u, for i, j in 0..3.
template <class ControlPoint>
NurbsSurface bicubic_patch(std::string name, ControlPoint point) {
  NurbsSurface s;
  s.name = std::move(name);
  s.degree_u = s.degree_v = 3;
  s.count_u = s.count_v = 4;
  s.knots_u = s.knots_v = {0, 0, 0, 0, 1, 1, 1, 1};
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j)
      s.control_points.push_back(point(i, j));
  }
  return s;
}

inline double uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

// A point drawn uniformly in the box [lo, hi].
inline Vec3 uniform_point(std::mt19937_64& rng, const Vec3& lo, const Vec3& hi) {
  return Vec3(uniform(rng, lo.x(), hi.x()), uniform(rng, lo.y(), hi.y()),
              uniform(rng, lo.z(), hi.z()));
}

// Clamped (or unclamped) knot vector with random interior knots; interior multiplicity <= max_mult.
inline std::vector<double> random_knots(std::mt19937_64& rng, int degree, int count, bool clamped,
                                        int max_mult = 1, double lo = 0.0, double hi = 1.0) {
  std::vector<double> knots;
  const int total = count + degree + 1;
  if (clamped) {
    knots.assign(degree + 1, lo);
    const int interior = count - degree - 1;
    std::vector<double> inner;
    while (static_cast<int>(inner.size()) < interior) {
      const double u = uniform(rng, lo, hi);
      const int mult = std::min<int>(1 + static_cast<int>(rng() % max_mult),
                                     interior - static_cast<int>(inner.size()));
      for (int m = 0; m < mult; ++m)
        inner.push_back(u);
    }
    std::sort(inner.begin(), inner.end());
    knots.insert(knots.end(), inner.begin(), inner.end());
    knots.insert(knots.end(), degree + 1, hi);
  } else {
    double u = lo;
    for (int i = 0; i < total; ++i) {
      knots.push_back(u);
      u += uniform(rng, 0.2, 1.0) * (hi - lo) / total;
    }
  }
  return knots;
}

inline NurbsCurve random_curve(std::uint64_t seed, int degree, int count, bool rational,
                               bool clamped = true, int dimension = 3) {
  std::mt19937_64 rng(seed);
  NurbsCurve c;
  c.name = "random";
  c.degree = degree;
  c.dimension = dimension;
  c.knots = random_knots(rng, degree, count, clamped, degree);
  for (int i = 0; i < count; ++i) {
    c.control_points.emplace_back(uniform(rng, -1, 1), uniform(rng, -1, 1),
                                  dimension == 3 ? uniform(rng, -1, 1) : 0.0);
    if (rational) c.weights.push_back(std::exp(uniform(rng, -1.5, 1.5)));
  }
  return c;
}

// A height-field-like freeform surface (x, y on a grid, random z), optionally rational.
inline NurbsSurface random_surface(std::uint64_t seed, int degree_u, int degree_v, int count_u,
                                   int count_v, bool rational, bool clamped = true) {
  std::mt19937_64 rng(seed);
  NurbsSurface s;
  s.name = "random";
  s.degree_u = degree_u;
  s.degree_v = degree_v;
  s.count_u = count_u;
  s.count_v = count_v;
  s.knots_u = random_knots(rng, degree_u, count_u, clamped, degree_u);
  s.knots_v = random_knots(rng, degree_v, count_v, clamped, degree_v);
  for (int i = 0; i < count_u; ++i) {
    for (int j = 0; j < count_v; ++j) {
      s.control_points.emplace_back(i + uniform(rng, -0.3, 0.3), j + uniform(rng, -0.3, 0.3),
                                    uniform(rng, -1.0, 1.0));
      if (rational) s.weights.push_back(std::exp(uniform(rng, -1.5, 1.5)));
    }
  }
  return s;
}

}  // namespace nurbsreg::test
