// The Newton's patch evaluation (surface/patch_derivatives.hpp): the unrolled kernels of fixed
// degrees against the generic loops they stand in for, bit for bit, on every degree pair up to
// kMaxDegree (those with a kernel and those without), polynomial and rational, at interior
// parameters and on the patch's edges; and both against BezierPatch::derivatives, an independent
// evaluation with other roundings (divisions instead of a reciprocal), to a relative tolerance.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "nurbsreg/engine/bezier.hpp"
#include "surface/patch_derivatives.hpp"

namespace nurbsreg::engine {
namespace {

BezierPatch random_patch(std::mt19937_64& rng, int p, int q, bool rational) {
  std::uniform_real_distribution<double> coordinate(-10.0, 10.0);
  std::uniform_real_distribution<double> weight(0.5, 2.0);
  BezierPatch patch;
  patch.degree_u = p;
  patch.degree_v = q;
  patch.param_u = {0.0, 1.0};
  patch.param_v = {0.0, 1.0};
  for (int k = 0; k < (p + 1) * (q + 1); ++k) {
    const double w = rational ? weight(rng) : 1.0;
    // Homogeneous: (w x, w y, w z, w).
    patch.cw.emplace_back(w * coordinate(rng), w * coordinate(rng), w * coordinate(rng), w);
  }
  return patch;
}

// The generic path of patch_derivatives_lanes (no fixed kernel).
void generic_derivatives(const BezierPatch& patch, double s, double t, Vec3* out) {
  double bu[3][kMaxDegree + 1], bv[3][kMaxDegree + 1];
  bernstein_012_loops(patch.degree_u, s, bu[0], bu[1], bu[2]);
  bernstein_012_loops(patch.degree_v, t, bv[0], bv[1], bv[2]);
  const double* const u_rows[3] = {bu[0], bu[1], bu[2]};
  const double* const v_rows[3] = {bv[0], bv[1], bv[2]};
  tensor_derivatives(patch.cw.data(), patch.degree_u, patch.degree_v, u_rows, v_rows,
                     unit_weights_of(patch), out);
}

TEST(PatchDerivatives, FixedDegreeKernelsEqualTheGenericLoopsBitForBit) {
  std::mt19937_64 rng(26);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int kernels = 0;
  for (int p = 1; p <= kMaxDegree; ++p) {
    for (int q = 1; q <= kMaxDegree; ++q) {
      for (const bool rational : {false, true}) {
        const BezierPatch patch = random_patch(rng, p, q, rational);
        const bool unit_weight = unit_weights_of(patch);
        EXPECT_EQ(unit_weight, !rational);
        Vec3 probe[3];
        const bool has_first = patch_first_derivatives(patch, 0.5, 0.5, unit_weight, probe);
        kernels += has_first;
        for (int k = 0; k < 12; ++k) {
          // The corners and edges first (Newton's box bounds), then interior points.
          const double s = k < 4 ? double(k % 2) : (k < 6 ? double(k - 4) : unit(rng));
          const double t = k < 4 ? double(k / 2) : (k < 6 ? unit(rng) : unit(rng));
          Vec3 fast[6], slow[6], reference[6];
          patch_derivatives(patch, s, t, unit_weight, fast);
          generic_derivatives(patch, s, t, slow);
          patch.derivatives(s, t, reference);
          for (int d = 0; d < 6; ++d) {
            for (int c = 0; c < 3; ++c) {
              ASSERT_EQ(fast[d][c], slow[d][c])
                  << "degree (" << p << ", " << q << ")" << (rational ? " rational" : "")
                  << ", derivative " << d << ", coordinate " << c << ", at (" << s << ", " << t
                  << ")";
              const double scale = 1e3 * (1.0 + std::abs(reference[d][c]));
              EXPECT_NEAR(fast[d][c], reference[d][c], 1e-12 * scale)
                  << "degree (" << p << ", " << q << "), derivative " << d;
            }
          }
          Vec3 first[3];
          if (patch_first_derivatives(patch, s, t, unit_weight, first)) {
            for (int d = 0; d < 3; ++d) {
              for (int c = 0; c < 3; ++c)
                ASSERT_EQ(first[d][c], fast[d][c])
                    << "first derivatives, degree (" << p << ", " << q << "), derivative " << d;
            }
          }
        }
      }
    }
  }
  // Every degree pair with a fixed kernel was met (and so compared): the planes, cylinders,
  // extrusions and lofts of the real parts, and the bicubics (patch_derivatives.hpp's list).
  EXPECT_EQ(kernels, 2 * 11);
}

}  // namespace
}  // namespace nurbsreg::engine
