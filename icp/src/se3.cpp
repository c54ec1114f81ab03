#include "nurbsreg/icp/se3.hpp"

#include <cmath>

namespace nurbsreg::icp {

Eigen::Matrix3d skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return m;
}

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& omega) {
  Vec6 xi = Vec6::Zero();
  xi.head<3>() = omega;
  return exp_se3(xi).linear();
}

Eigen::Vector3d log_so3(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

Eigen::Isometry3d exp_se3(const Vec6& xi) {
  const Eigen::Vector3d omega = xi.head<3>();
  const Eigen::Vector3d v = xi.tail<3>();
  const double theta = omega.norm();
  const Eigen::Matrix3d W = skew(omega);
  const Eigen::Matrix3d W2 = W * W;
  // A = sin(t)/t, B = (1 - cos t)/t^2, C = (t - sin t)/t^3; Taylor series below 1e-4 rad where
  // the closed forms lose digits to cancellation (the truncation error is O(t^4) ~ 1e-16).
  double A, B, C;
  if (theta < 1e-4) {
    const double t2 = theta * theta;
    A = 1.0 - t2 / 6.0;
    B = 0.5 - t2 / 24.0;
    C = 1.0 / 6.0 - t2 / 120.0;
  } else {
    A = std::sin(theta) / theta;
    B = (1.0 - std::cos(theta)) / (theta * theta);
    C = (theta - std::sin(theta)) / (theta * theta * theta);
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Matrix3d::Identity() + A * W + B * W2;
  T.translation() = (Eigen::Matrix3d::Identity() + B * W + C * W2) * v;
  return T;
}

Vec6 log_se3(const Eigen::Isometry3d& T) {
  const Eigen::AngleAxisd aa(Eigen::Matrix3d(T.linear()));
  const double theta = aa.angle();
  const Eigen::Vector3d omega = theta * aa.axis();
  const Eigen::Matrix3d W = skew(omega);
  // V^-1 = I - W/2 + D W^2 with D = (1 - t sin t / (2 (1 - cos t))) / t^2 -> 1/12 at t = 0.
  double D;
  if (theta < 1e-4) {
    D = 1.0 / 12.0 + theta * theta / 720.0;
  } else {
    D = (1.0 - theta * std::sin(theta) / (2.0 * (1.0 - std::cos(theta)))) / (theta * theta);
  }
  const Eigen::Matrix3d V_inv = Eigen::Matrix3d::Identity() - 0.5 * W + D * W * W;
  Vec6 xi;
  xi.head<3>() = omega;
  xi.tail<3>() = V_inv * T.translation();
  return xi;
}

Eigen::Matrix3d orthonormalize(const Eigen::Matrix3d& R) {
  return Eigen::Quaterniond(R).normalized().toRotationMatrix();
}

double rotation_angle(const Eigen::Isometry3d& T) {
  // atan2 form: accurate for tiny angles, unlike acos((trace - 1) / 2).
  const Eigen::Matrix3d R = T.linear();
  const Eigen::Vector3d axis_sin(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  return std::atan2(0.5 * axis_sin.norm(), 0.5 * (R.trace() - 1.0));
}

}  // namespace nurbsreg::icp
