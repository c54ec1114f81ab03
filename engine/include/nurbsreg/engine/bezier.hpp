#pragma once
// Rational Bézier pieces and patches in homogeneous form, each remembering the parameter box it
// covers in its parent NURBS entity, so results are reported in the parent's (u, v).

#include <array>
#include <vector>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine {

// Bernstein polynomials B_i^n(t), i = 0..n, into values[0..n]. n <= 2 * kMaxDegree.
void bernstein(int n, double t, double* values);

// de Casteljau: the control points points[i * stride], i = 0..n (n <= kMaxDegree), split at t
// into the parts over [0, t] (left) and [t, 1] (right), written at out_stride.
void de_casteljau_split(const Vec4* points, int stride, int n, double t, Vec4* left, Vec4* right,
                        int out_stride);

// A rational Bézier curve of degree <= kMaxDegree; local parameter t in [0, 1] maps to
// `param` in the parent curve. Fixed storage: copying and splitting never allocate.
struct BezierCurve {
  int degree = 0;
  std::array<Vec4, kMaxDegree + 1> cw{};  // homogeneous control points
  ParamInterval param;

  Vec3 point(int i) const { return cw[i].head<3>() / cw[i][3]; }
  double weight(int i) const { return cw[i][3]; }
  Vec3 evaluate(double t) const;
  // derivs[k] = d^k C / dt^k (local t) for k = 0..order, order <= 2.
  void derivatives(double t, int order, Vec3* derivs) const;
  // de Casteljau at local t: left covers [0, t], right [t, 1]; their `param` are mapped.
  void split(double t, BezierCurve& left, BezierCurve& right) const;
};

// A rational Bézier patch; local (s, t) in [0, 1]^2 maps to (param_u, param_v) in the parent.
// Control point (i, j) at cw[i * (degree_v + 1) + j]. Holds a std::vector: splitting allocates,
// so hot paths work on cached scalar forms instead (see the projectors).
struct BezierPatch {
  int degree_u = 0;
  int degree_v = 0;
  std::vector<Vec4> cw;
  ParamInterval param_u;
  ParamInterval param_v;

  int stride() const { return degree_v + 1; }
  const Vec4& at(int i, int j) const { return cw[i * (degree_v + 1) + j]; }
  Vec3 point(int i, int j) const { return at(i, j).head<3>() / at(i, j)[3]; }
  Vec3 evaluate(double s, double t) const;
  // S, S_s, S_t, S_ss, S_st, S_tt with respect to the local (s, t).
  void derivatives(double s, double t, Vec3* s_st_out /* [6]: S, Ss, St, Sss, Sst, Stt */) const;
  void split_u(double s, BezierPatch& low, BezierPatch& high) const;
  void split_v(double t, BezierPatch& low, BezierPatch& high) const;
};

}  // namespace nurbsreg::engine
