#pragma once
// Surfaces that make projection hard, shared by the warm-certificate and reach-bound tests: a
// hairpin (two layers close together), the same fold inside one patch, wavy sheets whose
// patches are C2 or C1 across their edges, a trough with two local minima in one patch, and a
// long rational cylinder strip.

#include <cmath>
#include <vector>

#include "nurbsreg/engine/model.hpp"
#include "nurbsreg/engine/nurbs_surface.hpp"

namespace nurbsreg::test {

using engine::Model;
using engine::NurbsSurface;
using engine::Vec3;

// A bicubic hairpin: the sheet runs out along x, turns around and comes back `gap` above itself.
inline NurbsSurface hairpin(double gap) {
  NurbsSurface s;
  s.name = "hairpin";
  s.degree_u = 3;
  s.degree_v = 3;
  const double xs[] = {10, 7, 4, 1.5, 0, -0.4, -0.4, 0, 1.5, 4, 7, 10};
  s.count_u = 12;
  s.count_v = 6;
  for (int k = 0; k <= 3; ++k)
    s.knots_u.push_back(0.0);
  for (int k = 1; k < s.count_u - 3; ++k)
    s.knots_u.push_back(static_cast<double>(k) / (s.count_u - 3));
  for (int k = 0; k <= 3; ++k)
    s.knots_u.push_back(1.0);
  s.knots_v = {0, 0, 0, 0, 1.0 / 3, 2.0 / 3, 1, 1, 1, 1};
  for (int i = 0; i < s.count_u; ++i) {
    for (int j = 0; j < s.count_v; ++j) {
      const double z = (i < 6 ? 0.0 : gap) + 0.2 * std::sin(0.7 * xs[i]) * std::cos(1.1 * j);
      s.control_points.emplace_back(xs[i], 1.2 * j, z);
    }
  }
  return s;
}

// The same fold inside one Bézier patch (degree 5 in u, one span): the other layer belongs to
// the anchor's own patch, outside its certificate's box N (so far the certificates refuse points
// between such layers: the rest of the patch is too close).
inline NurbsSurface folded_patch(double gap) {
  NurbsSurface s;
  s.name = "folded patch";
  s.degree_u = 5;
  s.degree_v = 3;
  const double xs[] = {10, 2, -1.5, -1.5, 2, 10};
  const double zs[] = {0, 0, 0, 1, 1, 1};
  s.count_u = 6;
  s.count_v = 4;
  s.knots_u = {0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1};
  s.knots_v = {0, 0, 0, 0, 1, 1, 1, 1};
  for (int i = 0; i < s.count_u; ++i) {
    for (int j = 0; j < s.count_v; ++j)
      s.control_points.emplace_back(xs[i], 1.5 * j, gap * zs[i] + 0.1 * std::cos(1.3 * j + i));
  }
  return s;
}

// A wavy bicubic sheet of n x n control points with uniform interior knots, each `multiplicity`
// times (1: C2, 2: C1; either way its certificates' boxes may span patches), over patches about a
// unit wide, with waves of about two patches.
inline NurbsSurface wavy_sheet(int n, int multiplicity) {
  NurbsSurface s;
  s.name = "wavy sheet";
  s.degree_u = 3;
  s.degree_v = 3;
  std::vector<double> knots(4, 0.0);
  const int spans = (n - 4) / multiplicity + 1;
  for (int k = 1; k < spans; ++k) {
    for (int m = 0; m < multiplicity; ++m)
      knots.push_back(static_cast<double>(k) / spans);
  }
  knots.insert(knots.end(), 4, 1.0);
  s.count_u = n;
  s.count_v = n;
  s.knots_u = knots;
  s.knots_v = knots;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      s.control_points.emplace_back(
          i, 1.1 * j, 0.6 * std::sin(0.9 * i + 0.3 * j) * std::cos(0.7 * j - 0.2 * i));
    }
  }
  return s;
}

// One Bézier patch of degree (2, 1), its 3 x 2 control points still to be added (u outer).
inline NurbsSurface quadratic_by_linear(const char* name) {
  NurbsSurface s;
  s.name = name;
  s.degree_u = 2;
  s.degree_v = 1;
  s.count_u = 3;
  s.count_v = 2;
  s.knots_u = {0, 0, 0, 1, 1, 1};
  s.knots_v = {0, 0, 1, 1};
  return s;
}

// A shallow parabolic trough, z = 0.04 (x - 5)^2 - 0.5 over x and y in [0, 10]: one polynomial
// (2, 1) patch, flat enough to be searched as itself. Above its centre of curvature (z = 12)
// the distance has two local minima, one on each slope.
inline NurbsSurface trough() {
  NurbsSurface s = quadratic_by_linear("trough");
  const double zs[] = {0.5, -1.5, 0.5};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 2; ++j)
      s.control_points.emplace_back(5.0 * i, 10.0 * j, zs[i]);
  }
  return s;
}

// A quarter of a cylinder about the z axis, `length` long: one rational (2, 1) patch, like the
// bores of NIST CTC-02 and linkrods (a few mm of radius, hundreds long).
inline NurbsSurface cylinder_strip(double radius, double length) {
  NurbsSurface s = quadratic_by_linear("cylinder strip");
  const Vec3 arc[3] = {{radius, 0, 0}, {radius, radius, 0}, {0, radius, 0}};
  const double w[3] = {1.0, std::sqrt(0.5), 1.0};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 2; ++j) {
      s.control_points.push_back(arc[i] + Vec3(0, 0, (j - 0.5) * length));
      s.weights.push_back(w[i]);
    }
  }
  return s;
}

inline Model model_of(std::vector<NurbsSurface> surfaces) {
  Model m;
  m.surfaces = std::move(surfaces);
  return m;
}

}  // namespace nurbsreg::test
