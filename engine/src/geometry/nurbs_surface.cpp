#include "nurbsreg/engine/nurbs_surface.hpp"

#include <algorithm>
#include <cmath>

#include "geometry/basis.hpp"
#include "geometry/validation.hpp"

namespace nurbsreg::engine {

Vec4 NurbsSurface::homogeneous(int i, int j) const {
  const double w = weight(i, j);
  const Vec3& p = point(i, j);
  return Vec4(w * p.x(), w * p.y(), w * p.z(), w);
}

ParamInterval NurbsSurface::domain_u() const {
  return {knots_u[degree_u], knots_u[count_u]};
}
ParamInterval NurbsSurface::domain_v() const {
  return {knots_v[degree_v], knots_v[count_v]};
}

std::optional<std::string> NurbsSurface::validate() const {
  if (auto e = detail::check_degree("degree[0] (u)", degree_u)) return e;
  if (auto e = detail::check_degree("degree[1] (v)", degree_v)) return e;
  if (auto e = detail::check_knots("knots_u", knots_u, degree_u, count_u)) return e;
  if (auto e = detail::check_knots("knots_v", knots_v, degree_v, count_v)) return e;
  if (control_points.size() != static_cast<std::size_t>(count_u) * count_v) {
    return "control_points: expected " + std::to_string(count_u) + " x " + std::to_string(count_v) +
           " points, got " + std::to_string(control_points.size());
  }
  for (int i = 0; i < count_u; ++i) {
    for (int j = 0; j < count_v; ++j) {
      if (!point(i, j).allFinite()) {
        return "control_points[" + std::to_string(i) + "][" + std::to_string(j) +
               "]: not a finite point";
      }
    }
  }
  if (!weights.empty()) {
    if (weights.size() != control_points.size()) {
      return "weights: expected " + std::to_string(count_u) + " x " + std::to_string(count_v) +
             " values, got " + std::to_string(weights.size());
    }
    for (int i = 0; i < count_u; ++i) {
      for (int j = 0; j < count_v; ++j) {
        const double w = weight(i, j);
        if (!std::isfinite(w) || !(w > 0.0)) {
          return "weights[" + std::to_string(i) + "][" + std::to_string(j) +
                 "]: must be a finite number > 0 (got " + detail::format_number(w) + ")";
        }
      }
    }
  }
  return validate_trim_loops();
}

std::optional<std::string> NurbsSurface::validate_trim_loops() const {
  for (std::size_t l = 0; l < trim_loops.size(); ++l) {
    const std::string loop = "trim_loops[" + std::to_string(l) + "]";
    if (trim_loops[l].curves.empty()) return loop + ".curves: a loop needs at least one curve";
    for (std::size_t c = 0; c < trim_loops[l].curves.size(); ++c) {
      const TrimCurve& curve = trim_loops[l].curves[c];
      const std::string field = loop + ".curves[" + std::to_string(c) + "]";
      if (auto e = curve.uv.validate()) return field + ".uv: " + *e;
      if (curve.uv.dimension != 2) {
        return field + ".uv: must be a 2-D curve in (u, v) (got dimension " +
               std::to_string(curve.uv.dimension) + ")";
      }
      if (curve.edge) {
        if (auto e = curve.edge->validate()) return field + ".edge: " + *e;
        if (curve.edge->dimension != 3) return field + ".edge: must be a 3-D curve";
        // The edge and its uv curve share their parameter (CAD's same-parameter property): an
        // edge hit reports (u, v) = uv(t).
        const ParamInterval a = curve.uv.domain(), b = curve.edge->domain();
        const double tol = 1e-9 * std::max({1.0, std::abs(a.lo), std::abs(a.hi)});
        if (std::abs(a.lo - b.lo) > tol || std::abs(a.hi - b.hi) > tol) {
          return field + ".edge: parameter domain [" + detail::format_number(b.lo) + ", " +
                 detail::format_number(b.hi) + "] differs from the uv curve's [" +
                 detail::format_number(a.lo) + ", " + detail::format_number(a.hi) + "]";
        }
      } else if (curve.uv.degree != 1) {
        return field + ": a uv curve of degree " + std::to_string(curve.uv.degree) +
               " needs its 3-D edge (only degree-1 uv curves are mapped to 3-D by the engine)";
      }
    }
  }
  return std::nullopt;
}

Vec3 NurbsSurface::evaluate(double u, double v) const {
  const ParamInterval du = domain_u();
  const ParamInterval dv = domain_v();
  u = std::clamp(u, du.lo, du.hi);
  v = std::clamp(v, dv.lo, dv.hi);
  const int span_u = find_span(degree_u, knots_u, count_u, u);
  const int span_v = find_span(degree_v, knots_v, count_v, v);
  double nu[kMaxDegree + 1];
  double nv[kMaxDegree + 1];
  basis_functions(span_u, u, degree_u, knots_u, nu);
  basis_functions(span_v, v, degree_v, knots_v, nv);
  Vec4 sum = Vec4::Zero();
  for (int a = 0; a <= degree_u; ++a) {
    Vec4 row = Vec4::Zero();
    for (int b = 0; b <= degree_v; ++b) {
      row += nv[b] * homogeneous(span_u - degree_u + a, span_v - degree_v + b);
    }
    sum += nu[a] * row;
  }
  return sum.head<3>() / sum[3];
}

SurfaceDerivatives NurbsSurface::derivatives(double u, double v) const {
  const ParamInterval du = domain_u();
  const ParamInterval dv = domain_v();
  u = std::clamp(u, du.lo, du.hi);
  v = std::clamp(v, dv.lo, dv.hi);
  const int span_u = find_span(degree_u, knots_u, count_u, u);
  const int span_v = find_span(degree_v, knots_v, count_v, v);
  double nu[kMaxDerivative + 1][kMaxDegree + 1];
  double nv[kMaxDerivative + 1][kMaxDegree + 1];
  basis_derivatives(span_u, u, degree_u, knots_u, 2, nu);
  basis_derivatives(span_v, v, degree_v, knots_v, 2, nv);
  // Homogeneous partials A^(k,l) (A3.6), k + l <= 2.
  Vec4 a[3][3];
  for (auto& row : a) {
    for (Vec4& x : row)
      x.setZero();
  }
  for (int r = 0; r <= degree_u; ++r) {
    Vec4 temp[3] = {Vec4::Zero(), Vec4::Zero(), Vec4::Zero()};
    for (int s = 0; s <= degree_v; ++s) {
      const Vec4 pw = homogeneous(span_u - degree_u + r, span_v - degree_v + s);
      for (int l = 0; l <= 2; ++l)
        temp[l] += nv[l][s] * pw;
    }
    for (int k = 0; k <= 2; ++k) {
      for (int l = 0; l + k <= 2; ++l)
        a[k][l] += nu[k][r] * temp[l];
    }
  }
  // Rational partials S^(k,l) (The NURBS Book A4.4).
  static constexpr double kBinomial[3][3] = {{1, 0, 0}, {1, 1, 0}, {1, 2, 1}};
  Vec3 s[3][3];
  for (auto& row : s) {
    for (Vec3& x : row)
      x.setZero();
  }
  for (int k = 0; k <= 2; ++k) {
    for (int l = 0; l + k <= 2; ++l) {
      Vec3 v2 = a[k][l].head<3>();
      for (int j = 1; j <= l; ++j)
        v2 -= kBinomial[l][j] * a[0][j][3] * s[k][l - j];
      for (int i = 1; i <= k; ++i) {
        v2 -= kBinomial[k][i] * a[i][0][3] * s[k - i][l];
        Vec3 v3 = Vec3::Zero();
        for (int j = 1; j <= l; ++j)
          v3 += kBinomial[l][j] * a[i][j][3] * s[k - i][l - j];
        v2 -= kBinomial[k][i] * v3;
      }
      s[k][l] = v2 / a[0][0][3];
    }
  }
  return {s[0][0], s[1][0], s[0][1], s[2][0], s[1][1], s[0][2]};
}

}  // namespace nurbsreg::engine
