#pragma once
// Internal to registration: the model's own discrete rotational symmetries, and the poses they
// make of a scan's winning pose. A part that a half turn maps onto itself fits a scan equally
// well in two poses; the sample consensus often finds only one of them, so the coarse stage
// asks the model itself which turns leave it unchanged (README "align": symmetric parts).

#include <Eigen/Geometry>
#include <functional>
#include <span>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/registration/global.hpp"
#include "nurbsreg/registration/model_features.hpp"

namespace nurbsreg::registration::detail {

// Rotations S (model frame, S != identity) with S(model) = model: every one of the model's
// area-uniform keypoints, turned by S, lies within 1% of a voxel of the model's surface (exact
// distances). Candidates are the k-fold turns (k = 2, 3, 4, 5, 6, 8) about the keypoints'
// principal axes through their centroid (a rigid symmetry fixes the centroid and permutes the
// principal axes), and half turns about axes in a plane of two equal spreads; the most
// promising are refined by an exact ICP of the turned keypoints, since the centroid and axes of
// samples are only estimates, and products of the turns found complete the group. An axis about
// which arbitrary turns fit (a surface of revolution) gives no discrete symmetry: that one is
// continuous, and the ICP's degeneracy report names it. Deterministic; sorted by angle.
// Its result is stored in the features cache: a change to what it finds must bump
// kModelFeaturesRevision (model_features.hpp).
std::vector<Eigen::Isometry3d> find_model_symmetries(const engine::PreparedModel& model,
                                                     const ModelKeypoints& keypoints, double voxel);

// For every model symmetry S not yet among the report's winner and alternatives (within 2
// degrees and a voxel): the pose S * winner, scored like the verified hypotheses (`score`);
// one that fits at least options.symmetry_ratio as well as the winner becomes an alternative,
// and its turn is named in report.symmetry.
void add_symmetric_alternatives(CoarseReport& report, std::span<const Eigen::Isometry3d> symmetries,
                                const std::function<PoseScore(const Eigen::Isometry3d&)>& score,
                                double voxel, const GlobalOptions& options);

}  // namespace nurbsreg::registration::detail
