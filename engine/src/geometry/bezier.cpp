#include "nurbsreg/engine/bezier.hpp"

#include "bernstein/de_casteljau.hpp"

#include <algorithm>
#include <cassert>

namespace nurbsreg::engine {
namespace {

constexpr int kMaxBernstein = 2 * kMaxDegree;

// d[k][i] = d^k/dt^k B_i^n(t), k = 0..order (order <= 2), i = 0..n.
void bernstein_derivatives(int n, double t, double (*d)[kMaxDegree + 1], int order = 2) {
  double lower[kMaxDegree + 1];
  for (int k = 0; k <= order; ++k) {
    for (int i = 0; i <= n; ++i)
      d[k][i] = 0.0;
  }
  bernstein(n, t, d[0]);
  if (n >= 1) {
    bernstein(n - 1, t, lower);
    for (int i = 0; i <= n; ++i) {
      d[1][i] = n * ((i >= 1 ? lower[i - 1] : 0.0) - (i <= n - 1 ? lower[i] : 0.0));
    }
  }
  if (n >= 2 && order >= 2) {
    bernstein(n - 2, t, lower);
    for (int i = 0; i <= n; ++i) {
      const double a = i >= 2 ? lower[i - 2] : 0.0;
      const double b = (i >= 1 && i - 1 <= n - 2) ? lower[i - 1] : 0.0;
      const double c = i <= n - 2 ? lower[i] : 0.0;
      d[2][i] = n * (n - 1) * (a - 2.0 * b + c);
    }
  }
}

// Rational derivatives from homogeneous ones (quotient rule, The NURBS Book eq. 4.8).
void rational_curve_derivatives(const Vec4* a, int order, Vec3* out) {
  out[0] = a[0].head<3>() / a[0][3];
  if (order >= 1) out[1] = (a[1].head<3>() - a[1][3] * out[0]) / a[0][3];
  if (order >= 2) {
    out[2] = (a[2].head<3>() - 2.0 * a[1][3] * out[1] - a[2][3] * out[0]) / a[0][3];
  }
}

}  // namespace

void de_casteljau_split(const Vec4* points, int stride, int n, double t, Vec4* left, Vec4* right,
                        int out_stride) {
  de_casteljau(points, stride, n, left, right, out_stride,
               [t](const Vec4& x, const Vec4& y) -> Vec4 { return (1.0 - t) * x + t * y; });
}

void bernstein(int n, double t, double* values) {
  assert(n <= kMaxBernstein);
  // The NURBS Book A1.3 (AllBernstein): a triangular scheme, stable for all t in [0, 1].
  values[0] = 1.0;
  const double t1 = 1.0 - t;
  for (int j = 1; j <= n; ++j) {
    double saved = 0.0;
    for (int k = 0; k < j; ++k) {
      const double temp = values[k];
      values[k] = saved + t1 * temp;
      saved = t * temp;
    }
    values[j] = saved;
  }
}

Vec3 BezierCurve::evaluate(double t) const {
  Vec3 d[1];
  derivatives(t, 0, d);
  return d[0];
}

void BezierCurve::derivatives(double t, int order, Vec3* derivs) const {
  double b[3][kMaxDegree + 1];
  bernstein_derivatives(degree, t, b, std::min(order, 2));
  Vec4 a[3] = {Vec4::Zero(), Vec4::Zero(), Vec4::Zero()};
  for (int k = 0; k <= order; ++k) {
    a[k].setZero();
    for (int i = 0; i <= degree; ++i)
      a[k] += b[k][i] * cw[i];
  }
  rational_curve_derivatives(a, order, derivs);
}

void BezierCurve::split(double t, BezierCurve& left, BezierCurve& right) const {
  // Copy first: left or right may alias *this.
  const BezierCurve self = *this;
  left.degree = right.degree = self.degree;
  de_casteljau_split(self.cw.data(), 1, self.degree, t, left.cw.data(), right.cw.data(), 1);
  const double mid = self.param.to_parent(t);
  left.param = {self.param.lo, mid};
  right.param = {mid, self.param.hi};
}

Vec3 BezierPatch::evaluate(double s, double t) const {
  double bu[kMaxBernstein + 1];
  double bv[kMaxBernstein + 1];
  bernstein(degree_u, s, bu);
  bernstein(degree_v, t, bv);
  Vec4 sum = Vec4::Zero();
  for (int i = 0; i <= degree_u; ++i) {
    Vec4 row = Vec4::Zero();
    for (int j = 0; j <= degree_v; ++j)
      row += bv[j] * at(i, j);
    sum += bu[i] * row;
  }
  return sum.head<3>() / sum[3];
}

void BezierPatch::derivatives(double s, double t, Vec3* out) const {
  double bu[3][kMaxDegree + 1];
  double bv[3][kMaxDegree + 1];
  bernstein_derivatives(degree_u, s, bu);
  bernstein_derivatives(degree_v, t, bv);
  Vec4 a[3][3];
  for (int k = 0; k <= 2; ++k) {
    for (int l = 0; l <= 2; ++l)
      a[k][l].setZero();
  }
  for (int i = 0; i <= degree_u; ++i) {
    Vec4 row[3] = {Vec4::Zero(), Vec4::Zero(), Vec4::Zero()};
    for (int j = 0; j <= degree_v; ++j) {
      for (int l = 0; l <= 2; ++l)
        row[l] += bv[l][j] * at(i, j);
    }
    for (int k = 0; k <= 2; ++k) {
      for (int l = 0; l + k <= 2; ++l)
        a[k][l] += bu[k][i] * row[l];
    }
  }
  const double w = a[0][0][3];
  const Vec3 p = a[0][0].head<3>() / w;
  const Vec3 ps = (a[1][0].head<3>() - a[1][0][3] * p) / w;
  const Vec3 pt = (a[0][1].head<3>() - a[0][1][3] * p) / w;
  const Vec3 pss = (a[2][0].head<3>() - 2.0 * a[1][0][3] * ps - a[2][0][3] * p) / w;
  const Vec3 ptt = (a[0][2].head<3>() - 2.0 * a[0][1][3] * pt - a[0][2][3] * p) / w;
  const Vec3 pst = (a[1][1].head<3>() - a[1][0][3] * pt - a[0][1][3] * ps - a[1][1][3] * p) / w;
  out[0] = p;
  out[1] = ps;
  out[2] = pt;
  out[3] = pss;
  out[4] = pst;
  out[5] = ptt;
}

void BezierPatch::split_u(double s, BezierPatch& low, BezierPatch& high) const {
  const BezierPatch self = *this;
  for (BezierPatch* out : {&low, &high}) {
    out->degree_u = self.degree_u;
    out->degree_v = self.degree_v;
    out->cw.resize(self.cw.size());
    out->param_v = self.param_v;
  }
  const int stride = self.stride();
  for (int j = 0; j <= self.degree_v; ++j) {
    de_casteljau_split(self.cw.data() + j, stride, self.degree_u, s, low.cw.data() + j,
                       high.cw.data() + j, stride);
  }
  const double mid = self.param_u.to_parent(s);
  low.param_u = {self.param_u.lo, mid};
  high.param_u = {mid, self.param_u.hi};
}

void BezierPatch::split_v(double t, BezierPatch& low, BezierPatch& high) const {
  const BezierPatch self = *this;
  for (BezierPatch* out : {&low, &high}) {
    out->degree_u = self.degree_u;
    out->degree_v = self.degree_v;
    out->cw.resize(self.cw.size());
    out->param_u = self.param_u;
  }
  const int stride = self.stride();
  for (int i = 0; i <= self.degree_u; ++i) {
    de_casteljau_split(self.cw.data() + i * stride, 1, self.degree_v, t, low.cw.data() + i * stride,
                       high.cw.data() + i * stride, 1);
  }
  const double mid = self.param_v.to_parent(t);
  low.param_v = {self.param_v.lo, mid};
  high.param_v = {mid, self.param_v.hi};
}

}  // namespace nurbsreg::engine
