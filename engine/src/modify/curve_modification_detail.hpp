#pragma once
// Internals shared by the curve_modification*.cpp files (not installed).

#include <Eigen/Dense>

#include "nurbsreg/engine/curve_modification.hpp"

namespace nurbsreg::engine::detail {

// The non-zero basis functions at a nose point: N_{first + k}(u), k = 0..degree.
struct BasisRow {
  int first = 0;
  int degree = 0;
  double values[kMaxDegree + 1] = {};
  // S_j = sum_i N_i(t_j) W_i, the denominator of the rational curve at t_j.
  double weight_sum = 0.0;
};

BasisRow basis_row(const NurbsCurve& curve, const NosePoint& nose);

// Solves A X = R (A: m x k, R: m x d) exactly when A is square and invertible, otherwise with
// the minimum-norm least-squares solution (complete orthogonal decomposition). `residual` is
// |A X - R|_F / |R|_F (0 when R is 0).
struct LinearSolution {
  Eigen::MatrixXd x;
  double residual = 0.0;
  int rank = 0;
};
LinearSolution solve_linear(const Eigen::MatrixXd& a, const Eigen::MatrixXd& r);

// Relative residual below which a solve counts as exact.
inline constexpr double kExactResidual = 1e-10;

// Copies the curve and makes its weights explicit (1 when non-rational).
NurbsCurve with_explicit_weights(const NurbsCurve& curve);

// Checks that noses and targets match and that the curve is valid; throws std::invalid_argument.
void check_inputs(const NurbsCurve& curve, std::span<const NosePoint> noses,
                  std::span<const Vec3> targets);

}  // namespace nurbsreg::engine::detail
