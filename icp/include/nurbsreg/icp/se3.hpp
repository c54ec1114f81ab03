#pragma once
// Rigid motions as twists. A twist xi = (omega, v) stacks a rotation vector omega [rad] and a
// translation v [model units]; exp_se3 / log_se3 are the exact exponential and logarithm of
// SE(3) (Barfoot, "State Estimation for Robotics", 2017, eqs. 7.83-7.86 and 7.95).
// All functions are pure and allocation-free.

#include <Eigen/Geometry>

namespace nurbsreg::icp {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

// Skew-symmetric matrix [w]x with [w]x a = w x a.
Eigen::Matrix3d skew(const Eigen::Vector3d& w);

// Rodrigues: rotation by angle |omega| about omega / |omega|.
Eigen::Matrix3d exp_so3(const Eigen::Vector3d& omega);
// Inverse of exp_so3 for angles in [0, pi).
Eigen::Vector3d log_so3(const Eigen::Matrix3d& R);

// T = exp(xi^): R = Rodrigues(omega), t = V(omega) v. Series expansions near omega = 0.
Eigen::Isometry3d exp_se3(const Vec6& xi);

// Inverse of exp_se3 for rotation angles in [0, pi).
Vec6 log_se3(const Eigen::Isometry3d& T);

// Nearest rotation matrix (via the unit quaternion), to remove drift after many updates.
Eigen::Matrix3d orthonormalize(const Eigen::Matrix3d& R);

// Rotation angle [rad] and translation length of a rigid motion: the size of a pose error.
double rotation_angle(const Eigen::Isometry3d& T);

}  // namespace nurbsreg::icp
