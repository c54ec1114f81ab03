// The warm-start certificate squared_distance_convex, checked independently of the Bézier
// bounds it uses: whenever it claims F = |S - p|^2 strictly convex on a whole patch, the Hessian
// of F computed from the patch's own derivatives (BezierPatch::derivatives) must be positive
// definite everywhere on a dense sample grid, and a Newton from any start must end at the
// clipping's global minimum of the patch. Polynomial and rational patches, points near and far,
// with a check that the certificate is not vacuous. (Checked to fail, thousands of times, when the
// certificate ignores the sign of F_ss.)
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/surface_projection.hpp"
#include "support/hessian_check.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::hessian_positive_definite;
using test::uniform;

struct Counts {
  int certified = 0;
  int points = 0;
};

Counts check_patches(const NurbsSurface& surface, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  Counts counts;
  SurfaceScratch scratch;
  for (const BezierPatch& patch : decompose(surface)) {
    const PreparedPatch pp = prepare_patch(patch);
    for (int k = 0; k < 40; ++k) {
      // Near the patch (offsets along the normal of up to 0.05 and 1 unit), and far away.
      const double s0 = uniform(rng, 0, 1), t0 = uniform(rng, 0, 1);
      Vec3 d[6];
      patch.derivatives(s0, t0, d);
      const Vec3 normal = d[1].cross(d[2]).normalized();
      const double offset = k < 20 ? uniform(rng, -0.05, 0.05)
                                   : (k < 35 ? uniform(rng, -1.0, 1.0) : uniform(rng, -20, 20));
      const Vec3 p = d[0] + offset * normal;
      ++counts.points;
      if (!squared_distance_convex(pp, p, scratch)) continue;
      ++counts.certified;
      for (int i = 0; i <= 16; ++i) {
        for (int j = 0; j <= 16; ++j) {
          EXPECT_TRUE(hessian_positive_definite(patch, p, i / 16.0, j / 16.0))
              << "certified but not convex at (" << i / 16.0 << ", " << j / 16.0 << ")";
        }
      }
      // A KKT point from any start is then the patch's global minimum (the clipping's answer).
      SurfaceHit exact;
      EXPECT_TRUE(project_onto_patch(pp, p, exact, scratch));
      for (int start = 0; start < 3; ++start) {
        double s = uniform(rng, 0, 1), t = uniform(rng, 0, 1);
        Vec3 foot;
        bool stationary = false;
        const double value = newton_on_patch(patch, p, 0.0, 1.0, 0.0, 1.0, s, t, foot, nullptr,
                                             nullptr, &stationary);
        if (!stationary) continue;
        EXPECT_NEAR(std::sqrt(value), std::sqrt(exact.distance_sq),
                    1e-9 * (1.0 + std::sqrt(exact.distance_sq)));
      }
    }
  }
  return counts;
}

// A random height field made gentle (jitter, heights and weight logarithms scaled by `flatness`),
// so that F is convex over whole patches for near points, as on real CAD panels.
NurbsSurface gentle_surface(std::uint64_t seed, int degree_u, int degree_v, int count_u,
                            int count_v, bool rational, double flatness) {
  NurbsSurface s = test::random_surface(seed, degree_u, degree_v, count_u, count_v, rational);
  // random_surface puts control point (i, j) at (i, j, 0) plus jitter: scale the jitter.
  for (int k = 0; k < static_cast<int>(s.control_points.size()); ++k) {
    const Vec3 grid(k / count_v, k % count_v, 0.0);
    s.control_points[k] = grid + flatness * (s.control_points[k] - grid);
  }
  for (double& w : s.weights)
    w = std::pow(w, flatness);
  return s;
}

TEST(WarmCertificate, PolynomialPatchesCertifiedOnlyWhereConvex) {
  for (int degree = 1; degree <= 5; ++degree) {
    const NurbsSurface surface = gentle_surface(100 + degree, degree, 3, degree + 4, 6, false, 0.1);
    const Counts counts = check_patches(surface, 7 + degree);
    if (degree >= 2) {
      // Not vacuous: a good share of the near points of these gently curved patches is certified.
      EXPECT_GT(counts.certified, counts.points / 8) << "degree " << degree;
    }
  }
}

TEST(WarmCertificate, RationalPatchesCertifiedOnlyWhereConvex) {
  const NurbsSurface surface = gentle_surface(31, 3, 3, 6, 6, true, 0.1);
  const Counts counts = check_patches(surface, 5);
  EXPECT_GT(counts.certified, counts.points / 20);
  // Strongly curved, strongly rational: whatever is certified must still hold (checked inside).
  check_patches(test::random_surface(32, 3, 3, 6, 6, true), 6);
  check_patches(test::random_surface(33, 4, 2, 7, 5, false), 7);
}

TEST(WarmCertificate, NonFinitePointIsNeverCertified) {
  const NurbsSurface surface = test::random_surface(3, 3, 3, 4, 4, false);
  const PreparedPatch pp = prepare_patch(decompose(surface).front());
  SurfaceScratch scratch;
  EXPECT_FALSE(squared_distance_convex(pp, Vec3(std::nan(""), 0, 0), scratch));
}

}  // namespace
}  // namespace nurbsreg::engine
