#include "nurbsreg/icp/degeneracy.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <cmath>
#include <cstdio>

namespace nurbsreg::icp {
namespace {

using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector3d;

// A number for a message: 4 significant digits, tiny values relative to `scale` shown as 0
// (so a direction reads "(0, 0, 1)" rather than "(1.2e-17, -3e-18, 1)").
std::string number(double x, double scale) {
  if (std::abs(x) <= 1e-9 * scale) x = 0.0;
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.4g", x);
  return buffer;
}

std::string vector_text(const Vector3d& v, double scale) {
  return "(" + number(v.x(), scale) + ", " + number(v.y(), scale) + ", " + number(v.z(), scale) +
         ")";
}

// Orthonormal basis (columns) of the span of `basis` (3 x d, orthonormal columns), rotated so
// that it is aligned with the coordinate axes as far as the subspace allows: repeatedly take
// the coordinate axis with the largest projection onto what is left of the subspace (first
// axis on ties), normalise it, and remove it. Signs: largest component positive.
MatrixXd axis_aligned_basis(MatrixXd basis) {
  const Eigen::Index d = basis.cols();
  MatrixXd out(3, d);
  for (Eigen::Index k = 0; k < d; ++k) {
    const MatrixXd P = basis * basis.transpose();  // projector onto the remaining subspace
    int best = 0;
    for (int a = 1; a < 3; ++a) {
      if (P.col(a).norm() > P.col(best).norm() + 1e-12) best = a;
    }
    Vector3d u = P.col(best).normalized();
    Eigen::Index arg;
    u.cwiseAbs().maxCoeff(&arg);
    if (u(arg) < 0.0) u = -u;
    out.col(k) = u;
    // Remove u from the subspace: re-orthonormalise the deflated basis, keeping d - k - 1
    // columns (the SVD's leading left singular vectors).
    const MatrixXd deflated = basis - u * (u.transpose() * basis);
    if (k + 1 < d) {
      Eigen::JacobiSVD<MatrixXd> svd(deflated, Eigen::ComputeThinU);
      basis = svd.matrixU().leftCols(d - k - 1);
    }
  }
  return out;
}

}  // namespace

std::string DegeneracyReport::describe() const {
  if (free_directions.empty()) return "none";
  std::string text;
  for (const FreeDirection& f : free_directions) {
    if (!text.empty()) text += "; ";
    text += f.description;
  }
  return text;
}

DegeneracyReport analyse_degeneracy(const Mat6& scaled_hessian, const Vector3d& center,
                                    double length_scale, double threshold) {
  DegeneracyReport report;
  report.center = center;
  report.length_scale = length_scale;
  report.threshold = threshold;
  const Eigen::SelfAdjointEigenSolver<Mat6> eigen(scaled_hessian);
  const double largest = eigen.eigenvalues()(5);
  report.eigenvectors = eigen.eigenvectors();
  if (!(largest > 0.0)) {
    report.relative_eigenvalues.setZero();
  } else {
    report.relative_eigenvalues = eigen.eigenvalues() / largest;
  }
  int free_count = 0;
  while (free_count < 6 && report.relative_eigenvalues(free_count) <= threshold)
    ++free_count;
  if (free_count == 0) return report;

  // Free subspace in physical twist coordinates about c: omega = omega_s / L, v = v_s.
  const MatrixXd N = report.eigenvectors.leftCols(free_count);
  const MatrixXd Omega = N.topRows(3) / length_scale;
  const MatrixXd V = N.bottomRows(3);

  // Pure translations in the free subspace: combinations a with Omega a = 0. Omega's columns
  // are O(1/L); singular values below 1e-6 / L count as zero.
  Eigen::JacobiSVD<MatrixXd> svd(Omega, Eigen::ComputeFullV);
  const Eigen::VectorXd sigma = svd.singularValues();
  Eigen::Index rotational = 0;
  while (rotational < sigma.size() && sigma(rotational) > 1e-6 / length_scale)
    ++rotational;
  const MatrixXd rotation_coeffs = svd.matrixV().leftCols(rotational);
  const MatrixXd translation_coeffs = svd.matrixV().rightCols(free_count - rotational);

  MatrixXd translations(3, 0);
  if (translation_coeffs.cols() > 0) {
    Eigen::JacobiSVD<MatrixXd> t_svd(V * translation_coeffs, Eigen::ComputeThinU);
    translations = axis_aligned_basis(t_svd.matrixU());
    for (Eigen::Index k = 0; k < translations.cols(); ++k) {
      FreeDirection f;
      f.kind = FreeDirection::Kind::translation;
      f.direction = translations.col(k);
      f.description = "translation along " + vector_text(f.direction, 1.0);
      report.free_directions.push_back(f);
    }
  }
  if (rotational > 0) {
    // Rotation axes: an aligned basis of the span of the omega parts; for each axis a the
    // free twist with that omega is found by least squares in the rotational coefficients,
    // and its translation made minimal by removing the free pure translations.
    const MatrixXd Omega_r = Omega * rotation_coeffs;  // 3 x r, full column rank
    const MatrixXd V_r = V * rotation_coeffs;
    Eigen::JacobiSVD<MatrixXd> o_svd(Omega_r, Eigen::ComputeThinU | Eigen::ComputeThinV);
    const MatrixXd axes = axis_aligned_basis(o_svd.matrixU());
    for (Eigen::Index k = 0; k < axes.cols(); ++k) {
      const Vector3d a = axes.col(k);
      const Eigen::VectorXd beta = o_svd.solve(a);
      Vector3d v = V_r * beta;
      if (translations.cols() > 0) v -= translations * (translations.transpose() * v);
      // Motion q -> a x (q - c) + v = a x (q - x) + h a with x = c + a x v, h = a . v
      // (Chasles: every twist is a screw about a unique axis).
      FreeDirection f;
      f.direction = a;
      f.pitch = a.dot(v);
      f.point = center + a.cross(v);
      const double point_scale = std::max(length_scale, center.norm());
      if (std::abs(f.pitch) <= 1e-6 * length_scale) {
        f.kind = FreeDirection::Kind::rotation;
        f.pitch = 0.0;
        f.description = "rotation about axis " + vector_text(a, 1.0) + " through " +
                        vector_text(f.point, point_scale);
      } else {
        f.kind = FreeDirection::Kind::screw;
        f.description = "screw about axis " + vector_text(a, 1.0) + " through " +
                        vector_text(f.point, point_scale) + " with pitch " +
                        number(f.pitch, length_scale) + " per rad";
      }
      report.free_directions.push_back(f);
    }
  }
  return report;
}

}  // namespace nurbsreg::icp
