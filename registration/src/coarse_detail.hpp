#pragma once
// Internal to registration: the steps of the global coarse alignment (global_alignment.cpp):
// descriptor matching (correspondences.cpp) and rigid hypotheses from the matches by sample
// consensus with pre-rejection (hypotheses.cpp).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <vector>

#include "features.hpp"
#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::registration::detail {

using ModelDescriptors = DescriptorMatrix;

struct Match {
  std::uint32_t scan = 0;   // row of the scan's descriptors
  std::uint32_t model = 0;  // row of the model's
  bool operator<(const Match& o) const { return scan != o.scan ? scan < o.scan : model < o.model; }
  bool operator==(const Match& o) const = default;
};

// Nearest neighbours in descriptor space both ways: every scan descriptor's nearest model
// descriptor and every model descriptor's nearest scan descriptor (the union, sorted, without
// duplicates; mutual nearest neighbours appear once). Brute force, exact and deterministic:
// distances |a|^2 + |b|^2 - 2 a.b in float with every sum in index order, the model's
// descriptors in vector lanes (AVX2 where the CPU has it: the same bits as the SSE2 version),
// ties to the lower index. Both matrices have kDescriptorSize columns (std::invalid_argument
// otherwise).
std::vector<Match> match_descriptors(const DescriptorMatrix& scan, const ModelDescriptors& model);

// Sample consensus guided by pairwise consistency (the idea behind maximum-consistent-set
// solvers such as TEASER++, Yang, Shi, Carlone 2020, used here to draw samples): two right
// matches keep the distance between their points, so for a seed match a, every right match is
// among the matches consistent with a (equal edge lengths within inlier_distance, ratio >=
// edge_similarity as in PCL's SampleConsensusPrerejective, edges >= min_edge). The second match
// is drawn from those, the third from those consistent with both: with 1% right matches among
// ten thousand, a right seed gives a right triple in about one draw of six, where plain random
// triples need a million draws.
struct RansacParams {
  int seeds = 1500;         // seed matches (a seeded subset when there are more)
  int draws_per_seed = 30;  // (b, c) draws per seed
  // A correspondence supports a pose when |T s - m| <= inlier_distance; also the edge-length
  // tolerance of two consistent matches.
  double inlier_distance = 1.0;
  double edge_similarity = 0.9;
  double min_edge = 1.0;
  // Hypotheses kept: the best `keep` by support that differ pairwise by more than
  // distinct_angle [rad] or distinct_translation.
  int keep = 12;
  // Hypotheses rank by overlap: how many of a fixed sample of the scan's keypoints land within
  // about two cells of this side of a model keypoint (then by support).
  double overlap_cell = 1.0;
  double distinct_angle = 0.2;
  double distinct_translation = 1.0;
  std::uint64_t seed = 1;
};

struct Hypothesis {
  Eigen::Isometry3d T_model_scan = Eigen::Isometry3d::Identity();
  std::size_t support = 0;  // matches within inlier_distance
  std::size_t overlap = 0;  // sampled scan keypoints near the model (RansacParams::overlap_cell)
};

// Guided sample consensus over the matches (RansacParams), the best pose of each seed (by
// support) kept when it ranks among the best by overlap,
// then a least-squares refit of each kept hypothesis on its supporting matches. Each seed has
// its own seeded stream; seeds are dealt to fixed chunks whose results merge in chunk order:
// the same hypotheses for any thread count. Best first. `scan` and `model` are the matched
// points (Match's rows); `model_surface` the points whose cells count as model for the overlap
// (all the model's keypoints: the described ones leave out its edges).
std::vector<Hypothesis> ransac_hypotheses(std::span<const engine::Vec3> scan,
                                          std::span<const engine::Vec3> model,
                                          std::span<const Match> matches,
                                          const RansacParams& params,
                                          std::span<const engine::Vec3> model_surface);

// Least-squares rigid motion taking src onto dst (Umeyama 1991, no scale); false when the
// points do not fix one (fewer than 3, or collinear).
bool fit_rigid(std::span<const engine::Vec3> src, std::span<const engine::Vec3> dst,
               Eigen::Isometry3d& T);

// Rotation angle [rad] and translation between two poses (as maps of the same scan).
double rotation_between(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);

// Two poses the coarse stage counts as one: within 2 degrees and a voxel of each other.
bool same_pose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double voxel);

}  // namespace nurbsreg::registration::detail
