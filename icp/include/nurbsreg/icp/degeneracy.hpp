#pragma once
// Which rigid motions a scan does not constrain, in words.
//
// The point-to-plane Hessian H = sum_i w_i J_i J_i^T with J_i = [(q_i - c) x n_i ; n_i]
// (rotation about the centroid c, then translation) has a null space exactly where the model
// surface slides into itself: a plane leaves 2 translations and the rotation about its
// normal, a sphere the 3 rotations about its centre, a cylinder the translation along and the
// rotation about its axis (Gelfand et al., "Geometrically stable sampling for the ICP
// algorithm", 3DIM 2003, section 3). Rotations and translations have different units, so the
// analysis uses scaled coordinates xi_s = (L omega, v) with L the RMS radius of the scan about
// its centroid: then every entry of J_s = [(q - c) x n / L ; n] is of order one and the
// eigenvalues of H_s / sum w are comparable (a unit of rotation moves the points by about L).

#include <string>
#include <vector>

#include "nurbsreg/icp/se3.hpp"

namespace nurbsreg::icp {

struct FreeDirection {
  enum class Kind { translation, rotation, screw };
  Kind kind = Kind::translation;
  // Unit translation direction, or unit rotation axis.
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
  // Rotations and screws: the point of the axis closest to the scan centroid (model frame).
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  // Screws: translation along the axis per radian of rotation (model units).
  double pitch = 0.0;
  // e.g. "translation along (0, 0, 1)", "rotation about axis (0, 0, 1) through (1, 2, 3)".
  std::string description;
};

struct DegeneracyReport {
  // Eigenvalues of H_s / sum(w), ascending, divided by the largest one (so in [0, 1]);
  // eigenvectors (columns) in scaled twist coordinates about `center`.
  Vec6 relative_eigenvalues = Vec6::Ones();
  Mat6 eigenvectors = Mat6::Identity();
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  // linearisation centroid c, model frame
  double length_scale = 1.0;                         // L
  double threshold = 0.0;  // relative eigenvalues <= threshold count as free
  // The free subspace in a canonical basis: pure translations first, aligned with the model
  // axes where the subspace allows it, then rotations (or screws) about axes likewise aligned.
  std::vector<FreeDirection> free_directions;

  bool degenerate() const { return !free_directions.empty(); }
  // "none" or the descriptions joined by "; ".
  std::string describe() const;
};

// Analyses the scaled Hessian H_s (see above) built about `center` with length scale L.
// Eigen-decomposition of a 6x6 matrix: deterministic, allocates only the description strings.
DegeneracyReport analyse_degeneracy(const Mat6& scaled_hessian, const Eigen::Vector3d& center,
                                    double length_scale, double threshold);

}  // namespace nurbsreg::icp
