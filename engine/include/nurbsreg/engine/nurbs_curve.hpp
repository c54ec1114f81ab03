#pragma once
// A NURBS curve as plain, editable data (2-D or 3-D, rational or not, clamped or unclamped).
// Evaluation is const, thread-safe and allocation-free.

#include <optional>
#include <string>
#include <vector>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine {

struct NurbsCurve {
  std::string name;
  int degree = 0;
  // 2 means every control point has z == 0 (the JSON gave two coordinates).
  int dimension = 3;
  // Non-decreasing, size == control_points.size() + degree + 1. Need not be clamped or
  // normalised; interior multiplicity at most `degree`.
  std::vector<double> knots;
  std::vector<Vec3> control_points;
  // Empty means non-rational (all weights 1); otherwise one weight > 0 per control point.
  std::vector<double> weights;

  int count() const { return static_cast<int>(control_points.size()); }
  bool is_rational() const { return !weights.empty(); }
  double weight(int i) const { return weights.empty() ? 1.0 : weights[i]; }
  Vec4 homogeneous(int i) const;
  // The parameter domain [knots[degree], knots[count]].
  ParamInterval domain() const;

  // An error naming the field ("knots: decreasing at index 4 (0.3 < 0.5)"), or nothing.
  std::optional<std::string> validate() const;

  // C(u); u outside the domain is clamped to it.
  Vec3 evaluate(double u) const;
  // derivs[k] = C^(k)(u) for k = 0..order, order <= kMaxDerivative (The NURBS Book A4.2).
  void derivatives(double u, int order, Vec3* derivs) const;
};

}  // namespace nurbsreg::engine
