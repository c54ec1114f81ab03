#pragma once
// Internal to registration: the fit verdict (verdict.cpp) and the description of a symmetry
// (symmetry.cpp).

#include <Eigen/Geometry>
#include <span>
#include <string>

#include "nurbsreg/engine/types.hpp"
#include "nurbsreg/icp/degeneracy.hpp"
#include "nurbsreg/registration/global.hpp"
#include "nurbsreg/registration/model_features.hpp"

namespace nurbsreg::registration::detail {

// The verdict on aligned scan points with their exact distances to the model (both in scan
// order, all points), the scan's noise estimate and its bounding-box diagonal.
FitVerdict judge_fit(std::span<const engine::Vec3> aligned, std::span<const double> distances,
                     double noise, double scan_diagonal, const ModelFeatures& features,
                     const VerdictOptions& options);

// The model's motion that takes the scan aligned by `winner` onto the scan aligned by
// `alternative` (alternative * winner^-1), in words: "rotation by 180.0 deg about (0, 0, 1)
// through (1, 2, 0)" (or a translation when it does not rotate).
std::string describe_symmetry(const Eigen::Isometry3d& winner,
                              const Eigen::Isometry3d& alternative);

// The motions that map the model onto itself where the scan lies (the final ICP's free
// directions: a surface of revolution turns about its axis, a plane slides and turns), in
// words: "continuous rotation about (0.000, 0.000, 1.000) through (0, 0, 20)"; empty when none.
std::string describe_continuous_symmetry(const icp::DegeneracyReport& degeneracy);

}  // namespace nurbsreg::registration::detail
