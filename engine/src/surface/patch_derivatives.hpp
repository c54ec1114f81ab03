#pragma once
// Internal: S, S_s, S_t, S_ss, S_st, S_tt of a rational Bézier patch at local (s, t), the inner
// cost of the box-constrained Newton. Definitions with internal linkage, for patch_newton.cpp
// alone: patch_derivatives has two versions under runtime dispatch (the AVX2 one does the four
// homogeneous coordinates in one pass), which only their own unit can dispatch to. Bit-identical
// to BezierPatch::derivatives' formulas, with one basis pass per direction, unrolled for the
// common degrees, in vector lanes.

#include <cstring>

#include "bernstein/bernstein_values.hpp"
#include "nurbsreg/engine/bezier.hpp"
#include "platform/cpu_dispatch.hpp"
#include "platform/vector_lanes.hpp"

namespace nurbsreg::engine {
namespace {

// S, S_s, S_t, S_ss, S_st, S_tt of a rational Bézier patch at local (s, t): homogeneous tensor
// sums, then the quotient rule (The NURBS Book eq. 4.20). The same formulas as
// BezierPatch::derivatives with one basis pass per direction and no zero-filled storage: the
// Newton iteration's inner cost.
// Every weight exactly 1 (a polynomial patch, as most CAD surfaces' are): the homogeneous sums are
// then the derivatives themselves, and the quotient rule (a division and ~50 operations, 9% of a
// warm frame's time) would only divide by sums of the Bernstein values that rounding keeps
// near 1 and 0. The caller knows it (NewtonPatch) and passes it to every evaluation.
[[gnu::always_inline]] inline bool unit_weights_of(const BezierPatch& patch) {
  const double* cw = patch.cw.data()->data();
  const int count = (patch.degree_u + 1) * (patch.degree_v + 1);
  bool unit = true;
  for (int k = 0; k < count; ++k)
    unit &= cw[4 * k + 3] == 1.0;
  return unit;
}

// The quotient rule from the six homogeneous sums a_kl = d^(k+l) A / ds^k dt^l (A = Σ B B P^w).
void rational_from_homogeneous(const Vec4& a00, const Vec4& a10, const Vec4& a01, const Vec4& a20,
                               const Vec4& a11, const Vec4& a02, Vec3* out) {
  const double inv_w = 1.0 / a00[3];
  const Vec3 x = a00.head<3>() * inv_w;
  const Vec3 xs = (a10.head<3>() - a10[3] * x) * inv_w;
  const Vec3 xt = (a01.head<3>() - a01[3] * x) * inv_w;
  out[0] = x;
  out[1] = xs;
  out[2] = xt;
  out[3] = (a20.head<3>() - 2.0 * a10[3] * xs - a20[3] * x) * inv_w;
  out[4] = (a11.head<3>() - a10[3] * xt - a01[3] * xs - a11[3] * x) * inv_w;
  out[5] = (a02.head<3>() - 2.0 * a01[3] * xt - a02[3] * x) * inv_w;
}

// The tensor sums of the homogeneous patch and its partial derivatives up to order 2, from the
// Bernstein values (and their derivatives) in s and t, then the rational quotient rule. Always
// inlined: called with constant degrees (below) the loops unroll fully.
[[gnu::always_inline]] inline void tensor_derivatives(const Vec4* cw, int p, int q,
                                                      const double* const bu[3],
                                                      const double* const bv[3], bool unit,
                                                      Vec3* out) {
  Vec4 a00 = Vec4::Zero(), a01 = Vec4::Zero(), a02 = Vec4::Zero(), a10 = Vec4::Zero(),
       a11 = Vec4::Zero(), a20 = Vec4::Zero();
  for (int i = 0; i <= p; ++i) {
    Vec4 r0 = Vec4::Zero(), r1 = Vec4::Zero(), r2 = Vec4::Zero();
    const Vec4* row = cw + i * (q + 1);
    for (int j = 0; j <= q; ++j) {
      r0 += bv[0][j] * row[j];
      r1 += bv[1][j] * row[j];
      r2 += bv[2][j] * row[j];
    }
    a00 += bu[0][i] * r0;
    a01 += bu[0][i] * r1;
    a02 += bu[0][i] * r2;
    a10 += bu[1][i] * r0;
    a11 += bu[1][i] * r1;
    a20 += bu[2][i] * r0;
  }
  if (unit) {
    out[0] = a00.head<3>();
    out[1] = a10.head<3>();
    out[2] = a01.head<3>();
    out[3] = a20.head<3>();
    out[4] = a11.head<3>();
    out[5] = a02.head<3>();
    return;
  }
  rational_from_homogeneous(a00, a10, a01, a20, a11, a02, out);
}

// patch_derivatives for fixed degrees (P, Q): the same sums, fully unrolled by the compiler, W
// homogeneous coordinates at a time (any W gives the same values, see kLanes).
template <int P, int Q, int W>
[[gnu::always_inline]] inline void patch_derivatives_fixed(const BezierPatch& patch, double s,
                                                           double t, bool unit, Vec3* out) {
  using Lanes = typename LanesOf<W>::type;
  const auto load_lanes = [](const double* x, Lanes& v) { std::memcpy(&v, x, sizeof v); };
  const auto store_lanes = [](double* x, const Lanes& v) { std::memcpy(x, &v, sizeof v); };
  double bu[3][P + 1], bv[3][Q + 1];
  bernstein_012_fixed<P>(s, bu[0], bu[1], bu[2]);
  bernstein_012_fixed<Q>(t, bv[0], bv[1], bv[2]);
  // Homogeneous sums a_kl = d^(k+l) A / ds^k dt^l, coordinate c at a_kl[c].
  alignas(32) double a00[4], a10[4], a01[4], a20[4], a11[4], a02[4];
  const double* cw = patch.cw.data()->data();  // (x, y, z, w) per control point, contiguous
  for (int h = 0; h < 4; h += W) {
    Lanes s00, s10, s01, s20, s11, s02;
    for (int i = 0; i <= P; ++i) {
      Lanes r0, r1, r2;
      {
        Lanes c;
        load_lanes(cw + 4 * (i * (Q + 1)) + h, c);
        r0 = bv[0][0] * c;
        r1 = bv[1][0] * c;
        r2 = bv[2][0] * c;
      }
      for (int j = 1; j <= Q; ++j) {
        Lanes c;
        load_lanes(cw + 4 * (i * (Q + 1) + j) + h, c);
        r0 += bv[0][j] * c;
        r1 += bv[1][j] * c;
        r2 += bv[2][j] * c;
      }
      if (i == 0) {
        s00 = bu[0][0] * r0;
        s01 = bu[0][0] * r1;
        s02 = bu[0][0] * r2;
        s10 = bu[1][0] * r0;
        s11 = bu[1][0] * r1;
        s20 = bu[2][0] * r0;
      } else {
        s00 += bu[0][i] * r0;
        s01 += bu[0][i] * r1;
        s02 += bu[0][i] * r2;
        s10 += bu[1][i] * r0;
        s11 += bu[1][i] * r1;
        s20 += bu[2][i] * r0;
      }
    }
    store_lanes(a00 + h, s00);
    store_lanes(a10 + h, s10);
    store_lanes(a01 + h, s01);
    store_lanes(a20 + h, s20);
    store_lanes(a11 + h, s11);
    store_lanes(a02 + h, s02);
  }
  if (unit) {
    for (int c = 0; c < 3; ++c) {
      out[0][c] = a00[c];
      out[1][c] = a10[c];
      out[2][c] = a01[c];
      out[3][c] = a20[c];
      out[4][c] = a11[c];
      out[5][c] = a02[c];
    }
    return;
  }
  // rational_from_homogeneous, coordinate by coordinate, with its expressions' evaluation order.
  const double inv_w = 1.0 / a00[3];
  const double w10 = a10[3], w01 = a01[3], w20 = a20[3], w11 = a11[3], w02 = a02[3];
  for (int c = 0; c < 3; ++c) {
    const double x = a00[c] * inv_w;
    const double xs = (a10[c] - w10 * x) * inv_w;
    const double xt = (a01[c] - w01 * x) * inv_w;
    out[0][c] = x;
    out[1][c] = xs;
    out[2][c] = xt;
    out[3][c] = (a20[c] - 2.0 * w10 * xs - w20 * x) * inv_w;
    out[4][c] = (a11[c] - w10 * xt - w01 * xs - w11 * x) * inv_w;
    out[5][c] = (a02[c] - 2.0 * w01 * xt - w02 * x) * inv_w;
  }
}

template <int W>
[[gnu::always_inline]] inline void patch_derivatives_lanes(const BezierPatch& patch, double s,
                                                           double t, bool unit, Vec3* out) {
  const int p = patch.degree_u, q = patch.degree_v;
  // The common degrees of CAD surfaces get unrolled code; any other takes the generic loops.
  if (p == 3 && q == 3) return patch_derivatives_fixed<3, 3, W>(patch, s, t, unit, out);
  if (p == 2 && q == 2) return patch_derivatives_fixed<2, 2, W>(patch, s, t, unit, out);
  if (p == 2 && q == 3) return patch_derivatives_fixed<2, 3, W>(patch, s, t, unit, out);
  if (p == 3 && q == 2) return patch_derivatives_fixed<3, 2, W>(patch, s, t, unit, out);
  // Lofted sheets (blades, hulls): cubic across, degree 8 along the span.
  if (p == 3 && q == 8) return patch_derivatives_fixed<3, 8, W>(patch, s, t, unit, out);
  if (p == 8 && q == 3) return patch_derivatives_fixed<8, 3, W>(patch, s, t, unit, out);
  // What most of a machined part's area is: planes (1, 1), cylinders and cones (rational (2, 1)),
  // extrusions and fillets of a cubic profile (3, 1), ruled faces.
  if (p == 1 && q == 1) return patch_derivatives_fixed<1, 1, W>(patch, s, t, unit, out);
  if (p == 2 && q == 1) return patch_derivatives_fixed<2, 1, W>(patch, s, t, unit, out);
  if (p == 1 && q == 2) return patch_derivatives_fixed<1, 2, W>(patch, s, t, unit, out);
  if (p == 3 && q == 1) return patch_derivatives_fixed<3, 1, W>(patch, s, t, unit, out);
  if (p == 1 && q == 3) return patch_derivatives_fixed<1, 3, W>(patch, s, t, unit, out);
  // Blends and lofts of higher degree (linkrods' degree-6 sweeps, the bearing's (4 and 5, 3)
  // faces): the loops' own overhead was a third of an evaluation at these sizes.
  if (p == 6 && q == 10) return patch_derivatives_fixed<6, 10, W>(patch, s, t, unit, out);
  if (p == 6 && q == 8) return patch_derivatives_fixed<6, 8, W>(patch, s, t, unit, out);
  if (p == 6 && q == 3) return patch_derivatives_fixed<6, 3, W>(patch, s, t, unit, out);
  if (p == 5 && q == 3) return patch_derivatives_fixed<5, 3, W>(patch, s, t, unit, out);
  if (p == 4 && q == 3) return patch_derivatives_fixed<4, 3, W>(patch, s, t, unit, out);
  double bu[3][kMaxDegree + 1], bv[3][kMaxDegree + 1];
  bernstein_012(p, s, bu[0], bu[1], bu[2]);
  bernstein_012(q, t, bv[0], bv[1], bv[2]);
  const double* const u_rows[3] = {bu[0], bu[1], bu[2]};
  const double* const v_rows[3] = {bv[0], bv[1], bv[2]};
  tensor_derivatives(patch.cw.data(), p, q, u_rows, v_rows, unit, out);
}

#if NURBSREG_HOT_VERSIONS
// Two versions instead of NURBSREG_HOT_CLONES: the AVX2 one does the four homogeneous
// coordinates in one 4-wide pass (kLanes is 2 in a portable build, also inside a clone).
NURBSREG_TARGET_V3
void patch_derivatives(const BezierPatch& patch, double s, double t, bool unit, Vec3* out) {
  patch_derivatives_lanes<4>(patch, s, t, unit, out);
}
NURBSREG_TARGET_DEFAULT
#endif
void patch_derivatives(const BezierPatch& patch, double s, double t, bool unit, Vec3* out) {
  patch_derivatives_lanes<kLanes>(patch, s, t, unit, out);
}

// S, S_s and S_t only (out[0..2]): the last evaluation of a Newton that is known to stop there
// needs no second derivatives. The same sums in the same order as tensor_derivatives and
// rational_from_homogeneous (or its unit-weight shortcut), so the three values are
// bit-identical to patch_derivatives'.
template <int P, int Q>
[[gnu::always_inline]] inline void patch_first_derivatives_fixed(const BezierPatch& patch, double s,
                                                                 double t, bool unit, Vec3* out) {
  double bu[3][P + 1], bv[3][Q + 1];
  bernstein_012_fixed<P>(s, bu[0], bu[1], bu[2]);
  bernstein_012_fixed<Q>(t, bv[0], bv[1], bv[2]);
  Vec4 a00 = Vec4::Zero(), a01 = Vec4::Zero(), a10 = Vec4::Zero();
  const Vec4* cw = patch.cw.data();
  for (int i = 0; i <= P; ++i) {
    Vec4 r0 = Vec4::Zero(), r1 = Vec4::Zero();
    const Vec4* row = cw + i * (Q + 1);
    for (int j = 0; j <= Q; ++j) {
      r0 += bv[0][j] * row[j];
      r1 += bv[1][j] * row[j];
    }
    a00 += bu[0][i] * r0;
    a01 += bu[0][i] * r1;
    a10 += bu[1][i] * r0;
  }
  if (unit) {
    out[0] = a00.head<3>();
    out[1] = a10.head<3>();
    out[2] = a01.head<3>();
    return;
  }
  const double inv_w = 1.0 / a00[3];
  const Vec3 x = a00.head<3>() * inv_w;
  out[0] = x;
  out[1] = (a10.head<3>() - a10[3] * x) * inv_w;
  out[2] = (a01.head<3>() - a01[3] * x) * inv_w;
}

// false when the degrees have no first-derivative kernel (the caller evaluates in full).
NURBSREG_HOT_CLONES
bool patch_first_derivatives(const BezierPatch& patch, double s, double t, bool unit, Vec3* out) {
  const int p = patch.degree_u, q = patch.degree_v;
  if (p == 3 && q == 3) return patch_first_derivatives_fixed<3, 3>(patch, s, t, unit, out), true;
  if (p == 2 && q == 2) return patch_first_derivatives_fixed<2, 2>(patch, s, t, unit, out), true;
  if (p == 2 && q == 3) return patch_first_derivatives_fixed<2, 3>(patch, s, t, unit, out), true;
  if (p == 3 && q == 2) return patch_first_derivatives_fixed<3, 2>(patch, s, t, unit, out), true;
  if (p == 3 && q == 8) return patch_first_derivatives_fixed<3, 8>(patch, s, t, unit, out), true;
  if (p == 8 && q == 3) return patch_first_derivatives_fixed<8, 3>(patch, s, t, unit, out), true;
  if (p == 1 && q == 1) return patch_first_derivatives_fixed<1, 1>(patch, s, t, unit, out), true;
  if (p == 2 && q == 1) return patch_first_derivatives_fixed<2, 1>(patch, s, t, unit, out), true;
  if (p == 1 && q == 2) return patch_first_derivatives_fixed<1, 2>(patch, s, t, unit, out), true;
  if (p == 3 && q == 1) return patch_first_derivatives_fixed<3, 1>(patch, s, t, unit, out), true;
  if (p == 1 && q == 3) return patch_first_derivatives_fixed<1, 3>(patch, s, t, unit, out), true;
  return false;
}

}  // namespace
}  // namespace nurbsreg::engine
