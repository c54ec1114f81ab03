#include "nurbsreg/engine/nurbs_curve.hpp"

#include <cmath>

#include "geometry/basis.hpp"
#include "geometry/validation.hpp"

namespace nurbsreg::engine {

Vec4 NurbsCurve::homogeneous(int i) const {
  const double w = weight(i);
  return Vec4(w * control_points[i].x(), w * control_points[i].y(), w * control_points[i].z(), w);
}

ParamInterval NurbsCurve::domain() const {
  return {knots[degree], knots[count()]};
}

std::optional<std::string> NurbsCurve::validate() const {
  if (auto e = detail::check_degree("degree", degree)) return e;
  if (dimension != 2 && dimension != 3) {
    return "control_points: points must have 2 or 3 coordinates";
  }
  if (auto e = detail::check_knots("knots", knots, degree, count())) return e;
  for (int i = 0; i < count(); ++i) {
    if (!control_points[i].allFinite()) {
      return "control_points[" + std::to_string(i) + "]: not a finite point";
    }
    if (dimension == 2 && control_points[i].z() != 0.0) {
      return "control_points[" + std::to_string(i) + "]: a 2-D curve has z == 0";
    }
  }
  if (!weights.empty()) {
    if (weights.size() != control_points.size()) {
      return "weights: expected " + std::to_string(count()) +
             " values (one per control point), got " + std::to_string(weights.size());
    }
    for (int i = 0; i < count(); ++i) {
      if (!std::isfinite(weights[i]) || !(weights[i] > 0.0)) {
        return "weights[" + std::to_string(i) + "]: must be a finite number > 0 (got " +
               detail::format_number(weights[i]) + ")";
      }
    }
  }
  return std::nullopt;
}

Vec3 NurbsCurve::evaluate(double u) const {
  Vec3 d[1];
  derivatives(u, 0, d);
  return d[0];
}

void NurbsCurve::derivatives(double u, int order, Vec3* derivs) const {
  const ParamInterval dom = domain();
  u = std::clamp(u, dom.lo, dom.hi);
  const int span = find_span(degree, knots, count(), u);
  double ders[kMaxDerivative + 1][kMaxDegree + 1];
  basis_derivatives(span, u, degree, knots, order, ders);
  // Homogeneous derivatives A^(k) (w-weighted points) and w^(k), then The NURBS Book A4.2.
  Vec4 aders[kMaxDerivative + 1] = {Vec4::Zero(), Vec4::Zero(), Vec4::Zero()};
  for (int k = 0; k <= order; ++k) {
    aders[k].setZero();
    for (int j = 0; j <= degree; ++j)
      aders[k] += ders[k][j] * homogeneous(span - degree + j);
  }
  static constexpr double kBinomial[3][3] = {{1, 0, 0}, {1, 1, 0}, {1, 2, 1}};
  for (int k = 0; k <= order; ++k) {
    Vec3 v = aders[k].head<3>();
    for (int i = 1; i <= k; ++i)
      v -= kBinomial[k][i] * aders[i][3] * derivs[k - i];
    derivs[k] = v / aders[0][3];
  }
}

}  // namespace nurbsreg::engine
