#pragma once
// Internal to registration: local geometry of the coarse stage's clouds. Normals by local PCA,
// the scan's noise level, and a sign-invariant variant of FPFH (Rusu, Blodow, Beetz, "Fast
// Point Feature Histograms (FPFH) for 3D registration", ICRA 2009).
//
// Why sign-invariant: a scan carries no viewpoint, so its PCA normals have arbitrary signs, and
// orienting them consistently (a minimum spanning tree over the cloud, Hoppe et al. 1992) costs
// more than the whole coarse stage and fails across thin walls, where it flips whole regions.
// FPFH's angles change with the signs; the absolute values of the cosines below do not, so the
// scan's and the model's (exact, outward) normals give the same histograms whatever their signs.
// Per pair (p_i, n_i), (p_j, n_j) with d = (p_j - p_i) / |p_j - p_i| and v = n_i x d / |n_i x d|:
//   |n_i . d|, |n_j . d|, |n_i . n_j|, |v . n_j|   (FPFH's phi and alpha, unsigned, and two more)
// each turned into its angle (from the plane, or between the normals) and binned on a
// square-root scale of the angle with soft bins (machined and smooth freeform parts have mostly
// small angles, which FPFH's linear bins of the cosines put all into one bin), 8 bins each: 32
// numbers. As in FPFH, a point's descriptor is its own
// histogram (SPFH) plus the mean of its neighbours' SPFHs, each block normalised to sum 100.
//
// All functions write by index and are deterministic for any thread count.

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "nurbsreg/engine/types.hpp"
#include "nurbsreg/registration/model_features.hpp"
#include "point_grid.hpp"

namespace nurbsreg::registration::detail {

inline constexpr int kBinsPerFeature = 8;
inline constexpr int kDescriptorSize = 4 * kBinsPerFeature;
using DescriptorMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Unit normals of `points` by PCA over the neighbours within `radius` (<= grid.cell(), the grid
// over `points`); valid[i] = 0 where fewer than `min_neighbours` neighbours or the
// neighbourhood is not a surface (no clear smallest eigenvalue: a line or a blob).
struct PcaNormals {
  std::vector<engine::Vec3> normals;
  std::vector<std::uint8_t> valid;
};
PcaNormals pca_normals(std::span<const engine::Vec3> points, const PointGrid& grid, double radius,
                       int min_neighbours);

// The points where PCA finds a surface (pca_normals over `radius`, at least
// kMinNormalNeighbours neighbours), with those normals, in point order: the points the coarse
// stage describes, on the scan and on the model alike. A descriptor compares normals, and the
// model's exact ones differ from a scan's PCA normals wherever the surface bends within the
// radius (NIST CTC-02's rims and fillets at a radius of two voxels); the points PCA rejects
// (edges, corners) are dropped on both sides, so that a descriptor's neighbours are the same
// kind of points on either. Described the same way, a half view of NIST CTC-02 found ten times
// as many right matches.
inline constexpr int kMinNormalNeighbours = 5;
using SurfacePoints = ModelKeypoints;  // points and their (here PCA) normals
SurfacePoints surface_points(std::span<const engine::Vec3> points, double radius);

// Descriptors (rows in point order) over the neighbours within `radius` (<= grid.cell()).
// The model's are stored in the features cache: a change to what this computes (bins, angles,
// weights) must bump kModelFeaturesRevision (model_features.hpp), or cached model descriptors
// stop matching fresh scan descriptors.
DescriptorMatrix describe(std::span<const engine::Vec3> points,
                          std::span<const engine::Vec3> normals, const PointGrid& grid,
                          double radius);

// The scan's noise level sigma (model units) along the surface normal, independent of any
// model: sqrt of the median smallest PCA eigenvalue of small neighbourhoods of a seeded subset
// of the scan, corrected for the degrees of freedom the plane fit takes. `voxel` (the model's
// sample spacing) caps the first neighbourhood radius (curvature inflates the estimate beyond
// it); the radius grows while the estimate exceeds a sixth of it (heavy noise: a ball no wider
// than the noise reads about a quarter of its radius). 0 when no neighbourhood has enough
// points (a very sparse scan).
double estimate_noise(std::span<const engine::Vec3> scan, double voxel, std::uint64_t seed);

}  // namespace nurbsreg::registration::detail
