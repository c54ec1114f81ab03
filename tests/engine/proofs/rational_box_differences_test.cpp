// rational_box_differences (proofs/warm_certificate.hpp), the bound behind rational warm
// certificates, checked against the functions it bounds, computed with nothing of it: for a query
// q = a + delta and a value m, G - H = N_q - N_a - (m - d^2) D = -2 delta . E' + k D with
// k = |delta|^2 - m + d^2, where D = W^2 and E' = W^2 (S - a) (W the patch's weight function, S
// the point). On a box N, in N's own coordinates (sigma, tau), its second derivatives are at most
// the degree factor times 2 |delta| e_X + |k| d_X (X = ss, tt, st: the grid of degree (2p, 2q)
// has second differences within those bounds). Here W and W S come from the homogeneous control
// points by de Casteljau, the derivatives by central differences; on random rational patches,
// anchors and boxes, and on the long cylinder strip where the whole patch's bound, scaled by the
// box's widths, was twenty times too wide. Not vacuous: the largest ratio of a derivative to its
// bound comes near 1 (a bound half as wide fails).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/surface_projection.hpp"
#include "proofs/warm_certificate.hpp"
#include "support/hard_surfaces.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::uniform;

// Homogeneous point sum B_i(s) B_j(t) (w P, w) of the patch (de Casteljau on each row, then on
// the column of results).
Vec4 homogeneous(const BezierPatch& patch, double s, double t) {
  const int p = patch.degree_u, q = patch.degree_v;
  std::vector<Vec4> column(static_cast<std::size_t>(p + 1));
  std::vector<Vec4> row(static_cast<std::size_t>(q + 1));
  for (int i = 0; i <= p; ++i) {
    for (int j = 0; j <= q; ++j)
      row[static_cast<std::size_t>(j)] = patch.at(i, j);
    for (int level = q; level > 0; --level) {
      for (int j = 0; j < level; ++j)
        row[j] = (1.0 - t) * row[j] + t * row[j + 1];
    }
    column[static_cast<std::size_t>(i)] = row[0];
  }
  for (int level = p; level > 0; --level) {
    for (int i = 0; i < level; ++i)
      column[i] = (1.0 - s) * column[i] + s * column[i + 1];
  }
  return column[0];
}

// -2 delta . E' + k D at local (s, t): E' = W (W S) - W^2 a, D = W^2.
double g_minus_h(const BezierPatch& patch, const Vec3& a, const Vec3& delta, double k, double s,
                 double t) {
  const Vec4 h = homogeneous(patch, s, t);
  const double w = h[3];
  const Vec3 e_prime = w * h.head<3>() - w * w * a;
  return -2.0 * delta.dot(e_prime) + k * w * w;
}

struct Worst {
  double ratio = 0.0;  // largest |derivative| / bound seen
};

// Second derivatives of G - H in N's coordinates at sample points of N against the bound.
void check_box(const PreparedPatch& pp, const Vec3& a, double s0, double s1, double t0, double t1,
               std::mt19937_64& rng, Worst& worst) {
  SurfaceScratch scratch;
  const BoxDifferences b = rational_box_differences(pp, a, s0, s1, t0, t1, scratch);
  const int p2 = 2 * pp.patch.degree_u, q2 = 2 * pp.patch.degree_v;
  const double ws = s1 - s0, wt = t1 - t0;
  const double size = pp.sphere.radius;
  for (int trial = 0; trial < 6; ++trial) {
    const Vec3 delta = uniform(rng, 0.0, 0.5 * size) *
                       Vec3(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    const double k = uniform(rng, -1.0, 1.0) * size * size;
    const double bound_ss =
        double(p2) * (p2 - 1) * (2.0 * delta.norm() * b.e_ss + std::abs(k) * b.d_ss);
    const double bound_tt =
        double(q2) * (q2 - 1) * (2.0 * delta.norm() * b.e_tt + std::abs(k) * b.d_tt);
    const double bound_st = double(p2) * q2 * (2.0 * delta.norm() * b.e_st + std::abs(k) * b.d_st);
    const auto f = [&](double sigma, double tau) {
      return g_minus_h(pp.patch, a, delta, k, s0 + sigma * ws, t0 + tau * wt);
    };
    constexpr double h = 1e-3;
    for (int n = 0; n < 12; ++n) {
      const double sigma = uniform(rng, h, 1.0 - h), tau = uniform(rng, h, 1.0 - h);
      const double f0 = f(sigma, tau);
      const double ss = (f(sigma + h, tau) - 2.0 * f0 + f(sigma - h, tau)) / (h * h);
      const double tt = (f(sigma, tau + h) - 2.0 * f0 + f(sigma, tau - h)) / (h * h);
      const double st = (f(sigma + h, tau + h) - f(sigma + h, tau - h) - f(sigma - h, tau + h) +
                         f(sigma - h, tau - h)) /
                        (4.0 * h * h);
      // The differences' own error: h^2 / 12 of a fourth derivative, and rounding.
      const double slack = 1e-5 * (bound_ss + bound_tt + bound_st) + 1e-9 * size * size * size;
      EXPECT_LE(std::abs(ss), bound_ss + slack) << "ss at (" << sigma << ", " << tau << ")";
      EXPECT_LE(std::abs(tt), bound_tt + slack) << "tt at (" << sigma << ", " << tau << ")";
      EXPECT_LE(std::abs(st), bound_st + slack) << "st at (" << sigma << ", " << tau << ")";
      // The ratio where the bound stands clear of the differences' own noise.
      if (bound_ss > 100.0 * slack) worst.ratio = std::max(worst.ratio, std::abs(ss) / bound_ss);
      if (bound_tt > 100.0 * slack) worst.ratio = std::max(worst.ratio, std::abs(tt) / bound_tt);
    }
  }
}

TEST(RationalBoxDifferences, BoundTheSecondDerivativesOfTheQuerysChange) {
  std::mt19937_64 rng(83);
  Worst worst;
  int boxes = 0;
  for (int seed = 0; seed < 6; ++seed) {
    const int degree_u = 2 + seed % 3, degree_v = 1 + seed % 3;
    const NurbsSurface surface = test::random_surface(200 + seed, degree_u, degree_v,
                                                      degree_u + 2 + seed % 2, degree_v + 2, true);
    for (const BezierPatch& patch : decompose(surface)) {
      const PreparedPatch pp = prepare_patch(patch);
      if (!pp.rational) continue;
      for (int n = 0; n < 4; ++n) {
        const double s = uniform(rng, 0, 1), t = uniform(rng, 0, 1);
        const Vec3 a = patch.evaluate(s, t) + Vec3(uniform(rng, -0.3, 0.3), uniform(rng, -0.3, 0.3),
                                                   uniform(rng, -0.3, 0.3));
        const double hs = uniform(rng, 0.02, 0.5), ht = uniform(rng, 0.02, 0.5);
        check_box(pp, a, std::max(0.0, s - hs), std::min(1.0, s + hs), std::max(0.0, t - ht),
                  std::min(1.0, t + ht), rng, worst);
        ++boxes;
      }
    }
  }
  std::printf("[ report ] %d boxes, largest derivative / bound %.3f\n", boxes, worst.ratio);
  EXPECT_GT(boxes, 40);
  EXPECT_GT(worst.ratio, 0.5);
}

// A quarter cylinder of radius 5, 400 long (NIST's and linkrods' bores): a box of a few degrees
// and a few mm about a mid-strip anchor.
TEST(RationalBoxDifferences, HoldOnALongCylinderStripAndAreItsOwnSize) {
  const double radius = 5.0, length = 400.0;
  const NurbsSurface s = test::cylinder_strip(radius, length);
  const PreparedPatch pp = prepare_patch(decompose(s).front());
  ASSERT_TRUE(pp.rational);
  std::mt19937_64 rng(89);
  Worst worst;
  const Vec3 a = pp.patch.evaluate(0.5, 0.5) + Vec3(0.01, 0.02, 0.0);
  check_box(pp, a, 0.4, 0.6, 0.49, 0.51, rng, worst);
  check_box(pp, a, 0.25, 0.75, 0.495, 0.505, rng, worst);
  std::printf("[ report ] cylinder strip: largest derivative / bound %.3f\n", worst.ratio);
  EXPECT_GT(worst.ratio, 0.3);
  // The arc's second differences about a mid-strip anchor are of the radius' size, not of the
  // strip's length (the anchor is 200 from either control row).
  SurfaceScratch scratch;
  const BoxDifferences b = rational_box_differences(pp, a, 0.4, 0.6, 0.49, 0.51, scratch);
  EXPECT_LT(b.e_ss, 0.04 * radius);
}

}  // namespace
}  // namespace nurbsreg::engine
