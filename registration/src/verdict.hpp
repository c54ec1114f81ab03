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

// The distance within which a point counts as an inlier for the verdict: options'
// tolerance_sigmas x the scan's noise, at least a floor from its bounding-box diagonal (and,
// when the noise could not be estimated (0), from the model's sample spacing `voxel`).
double fit_tolerance(double noise, double scan_diagonal, double voxel,
                     const VerdictOptions& options);

// A robust noise sigma from exact point-to-model distances: the median of those within `window`
// over the median of |Z| for a standard normal Z truncated at 3 (the window is 3 x the scan's
// noise estimate). 0 when fewer than kMinFitNoisePoints lie within the window.
inline constexpr std::size_t kMinFitNoisePoints = 100;
double fit_noise(std::span<const double> distances, double window);

// The verdict on aligned scan points with their exact distances to the model (both in scan
// order, all points), the scan's noise estimate and its bounding-box diagonal.
FitVerdict judge_fit(std::span<const engine::Vec3> aligned, std::span<const double> distances,
                     double noise, double scan_diagonal, const ModelFeatures& features,
                     const VerdictOptions& options);

// The resolution of the lengths in the symmetry texts, in sample spacings (voxels).
inline constexpr double kSymmetryTextVoxels = 0.01;

// The model's motion that takes the scan aligned by `winner` onto the scan aligned by
// `alternative` (alternative * winner^-1), in words: "rotation by 180.0 deg about (0.000, 0.000,
// 1.000) through (1.00, 2.00, 0.00)" (or a translation when it does not rotate). Lengths are
// rounded to `resolution` (model units; the callers give a hundredth of the sample spacing).
std::string describe_symmetry(const Eigen::Isometry3d& winner, const Eigen::Isometry3d& alternative,
                              double resolution);

// The motions that map the model onto itself where the scan lies (the final ICP's free
// directions: a surface of revolution turns about its axis, a plane slides and turns), in
// words: "continuous rotation about (0.000, 0.000, 1.000) through (0, 0, 20)"; empty when none.
std::string describe_continuous_symmetry(const icp::DegeneracyReport& degeneracy,
                                         double resolution);

}  // namespace nurbsreg::registration::detail
