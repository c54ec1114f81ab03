// The PCL peer of bench/align_global/run.py: PCL's SampleConsensusPrerejective on PCL FPFH
// features, then PCL's point-to-plane ICP (IterativeClosestPointWithNormals) on a dense model
// sampling, the pipeline of PCL's "Robust pose estimation of rigid objects" tutorial with the
// settings of run.py's Open3D peers (the same voxel, radii and distances). The model cloud's
// normals and features are computed once per process (excluded from the times, as run.py does
// for Open3D and nurbsreg); each scan is then timed from its downsampling on.
//
//   pcl_global_peer --model-cloud dense.pcd --voxel V [--threads N] [--iterations K] scan.pcd...
//
// prints one line per scan: the scan's path, the 4x4 pose (model_point = T * scan_point) row by
// row, wall and CPU seconds, and whether the sample consensus converged. PCL stays in bench/.
#include <pcl/features/fpfh_omp.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#include <pcl/registration/sample_consensus_prerejective.h>
#include <pcl/search/kdtree.h>
#include <time.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

using Point = pcl::PointNormal;
using Cloud = pcl::PointCloud<Point>;
using Features = pcl::PointCloud<pcl::FPFHSignature33>;

double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

Cloud::Ptr load(const std::string& path) {
  pcl::PointCloud<pcl::PointXYZ> xyz;
  if (pcl::io::loadPCDFile(path, xyz) != 0) {
    std::fprintf(stderr, "error: %s: PCL cannot read it\n", path.c_str());
    std::exit(3);
  }
  Cloud::Ptr out(new Cloud);
  pcl::copyPointCloud(xyz, *out);
  return out;
}

Cloud::Ptr downsample(const Cloud::Ptr& in, double voxel) {
  pcl::VoxelGrid<Point> grid;
  grid.setLeafSize(static_cast<float>(voxel), static_cast<float>(voxel), static_cast<float>(voxel));
  grid.setInputCloud(in);
  Cloud::Ptr out(new Cloud);
  grid.filter(*out);
  return out;
}

// Normals within `radius` (at most 30 neighbours are what Open3D's hybrid search uses; PCL's
// radius search takes all), written into the cloud's normal fields.
void estimate_normals(const Cloud::Ptr& cloud, double radius, int threads) {
  pcl::NormalEstimationOMP<Point, Point> ne(threads);
  ne.setInputCloud(cloud);
  ne.setRadiusSearch(radius);
  ne.compute(*cloud);
}

Features::Ptr fpfh(const Cloud::Ptr& cloud, double radius, int threads) {
  pcl::FPFHEstimationOMP<Point, Point, pcl::FPFHSignature33> fe(threads);
  fe.setInputCloud(cloud);
  fe.setInputNormals(cloud);
  fe.setRadiusSearch(radius);
  Features::Ptr out(new Features);
  fe.compute(*out);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  std::string model_path;
  double voxel = 0.0;
  int threads = 1;
  int iterations = 50000;  // PCL's tutorial; each costs a 33-D feature search
  std::vector<std::string> scans;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--model-cloud" && i + 1 < argc) {
      model_path = argv[++i];
    } else if (a == "--voxel" && i + 1 < argc) {
      voxel = std::atof(argv[++i]);
    } else if (a == "--iterations" && i + 1 < argc) {
      iterations = std::atoi(argv[++i]);
    } else if (a == "--threads" && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else if (!a.empty() && a[0] != '-') {
      scans.push_back(a);
    } else {
      std::fprintf(
          stderr,
          "usage: %s --model-cloud M.pcd --voxel V [--threads N] [--iterations K] scan.pcd...\n",
          argv[0]);
      return 2;
    }
  }
  if (model_path.empty() || !(voxel > 0.0) || threads < 1) {
    std::fprintf(stderr, "error: --model-cloud and a positive --voxel are required\n");
    return 2;
  }
  // The model: the dense sampling (for ICP) and its voxelised copy with features.
  const Cloud::Ptr dense = load(model_path);
  estimate_normals(dense, 2.0 * voxel, threads);
  const Cloud::Ptr target = downsample(dense, voxel);
  estimate_normals(target, 2.0 * voxel, threads);
  const Features::Ptr target_features = fpfh(target, 5.0 * voxel, threads);

  for (const std::string& path : scans) {
    const Cloud::Ptr scan = load(path);
    const auto wall0 = std::chrono::steady_clock::now();
    const double cpu0 = cpu_seconds();
    const Cloud::Ptr source = downsample(scan, voxel);
    estimate_normals(source, 2.0 * voxel, threads);
    const Features::Ptr source_features = fpfh(source, 5.0 * voxel, threads);

    pcl::SampleConsensusPrerejective<Point, Point, pcl::FPFHSignature33> sac;
    sac.setInputSource(source);
    sac.setSourceFeatures(source_features);
    sac.setInputTarget(target);
    sac.setTargetFeatures(target_features);
    sac.setMaximumIterations(iterations);
    sac.setNumberOfSamples(3);
    sac.setCorrespondenceRandomness(3);  // among the 3 nearest features
    sac.setSimilarityThreshold(0.9f);    // Open3D peer: edge-length checker 0.9
    sac.setMaxCorrespondenceDistance(1.5 * voxel);
    sac.setInlierFraction(0.25f);
    Cloud aligned;
    sac.align(aligned);
    const bool converged = sac.hasConverged();
    Eigen::Matrix4f coarse = sac.getFinalTransformation();

    // Point-to-plane ICP of the whole scan on the dense model (its normals), from the coarse
    // pose, as the Open3D peers: at most 50 iterations within one voxel.
    estimate_normals(scan, 2.0 * voxel, threads);
    pcl::IterativeClosestPointWithNormals<Point, Point> icp;
    icp.setInputSource(scan);
    icp.setInputTarget(dense);
    icp.setMaxCorrespondenceDistance(1.0 * voxel);
    icp.setMaximumIterations(50);
    icp.setTransformationEpsilon(1e-12);
    icp.setEuclideanFitnessEpsilon(1e-12);
    Cloud refined;
    icp.align(refined, coarse);
    const Eigen::Matrix4f T = icp.hasConverged() ? icp.getFinalTransformation() : coarse;
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    const double cpu = cpu_seconds() - cpu0;
    std::printf("%s", path.c_str());
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        std::printf(" %.9g", static_cast<double>(T(r, c)));
    std::printf(" %.4f %.4f %d\n", wall, cpu, converged ? 1 : 0);
    std::fflush(stdout);
  }
  return 0;
}
