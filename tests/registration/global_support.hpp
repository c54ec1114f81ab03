#pragma once
// Shared by the tests of the alignment from any pose: each model, prepared, and its coarse-stage
// features built once per test process and reused by every trial (as `batch` and the service
// reuse them), seeded random poses over all of SO(3), pose errors, and synthetic models with a
// known symmetry.
#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <memory>
#include <numbers>
#include <random>
#include <string>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/registration/alignment.hpp"
#include "nurbsreg/registration/model_features.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::registration::testing {

inline const std::string kReal = nurbsreg::test::shared_dir() + "/data/real/";
inline const std::string kPanel = nurbsreg::test::examples_dir() + "/panel.json";

struct Part {
  std::unique_ptr<engine::PreparedModel> model;
  std::shared_ptr<const ModelFeatures> features;
  double size = 0.0;  // the trimmed faces' box diagonal
};

// The prepared model and its features, once per path and process (a STEP part takes seconds to
// convert, its features about as long).
inline const Part& part(const std::string& path) {
  static std::map<std::string, Part> parts;
  Part& p = parts[path];
  if (!p.model) {
    p.model = std::make_unique<engine::PreparedModel>(io::read_model_file(path));
    p.features = std::make_shared<const ModelFeatures>(*p.model);
    p.size = p.model->geometry_bounds().box.diagonal();
  }
  return p;
}

// Uniform over SO(3) (a normalised Gaussian quaternion), translation up to 2 model sizes.
inline Eigen::Isometry3d random_pose(std::mt19937_64& rng, double size) {
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::Quaterniond q(g(rng), g(rng), g(rng), g(rng));
  q.normalize();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.toRotationMatrix();
  T.translation() = engine::Vec3(g(rng), g(rng), g(rng)).normalized() * size *
                    std::uniform_real_distribution<double>(0.0, 2.0)(rng);
  return T;
}

struct Errors {
  double degrees = 0.0;
  double translation = 0.0;
};

inline Errors pose_error(const Eigen::Isometry3d& truth, const Eigen::Isometry3d& found) {
  const Eigen::Isometry3d e = truth * found.inverse();
  return {Eigen::AngleAxisd(e.linear()).angle() * 180.0 / std::numbers::pi, e.translation().norm()};
}

// gmsh's as1-tu-203 assembly (a half turn about its vertical axis maps it onto itself) scanned
// from a far pose with 15% uniform outliers in the scan's box, noise 1e-4 of its size.
inline const std::string kSymmetricAssembly = kReal + "gmsh/as1-tu-203.stp";
inline engine::SyntheticScan cluttered_assembly_scan(std::size_t points) {
  const Part& p = part(kSymmetricAssembly);
  engine::SyntheticScanOptions o;
  o.points = points;
  o.noise_sigma = 1e-4 * p.size;
  o.outlier_fraction = 0.15;
  o.seed = 3;
  o.T_scan_model = engine::pose_from_euler_degrees(130, -40, 75, engine::Vec3(300, -120, 50));
  return engine::make_synthetic_scan(p.model->model(), o);
}

// A surface of revolution about the z axis: the quadratic Bezier profile (radius, height)
// (20, 0), (34, 20), (14, 40) swept by the exact rational quadratic circle (nine control points,
// weights 1 and sqrt(2)/2). Every rotation about z maps it onto itself, and no other motion
// does (the profile is not mirror-symmetric in height).
inline engine::Model revolved_part() {
  engine::NurbsSurface s;
  s.name = "vase";
  s.degree_u = 2;  // the circle
  s.degree_v = 2;  // the profile
  s.knots_u = {0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1};
  s.knots_v = {0, 0, 0, 1, 1, 1};
  s.count_u = 9;
  s.count_v = 3;
  const double r[3] = {20.0, 34.0, 14.0};
  const double z[3] = {0.0, 20.0, 40.0};
  const double h = std::sqrt(0.5);
  // The unit circle's control net: the square's corners carry weight sqrt(2)/2.
  const double cx[9] = {1, 1, 0, -1, -1, -1, 0, 1, 1};
  const double cy[9] = {0, 1, 1, 1, 0, -1, -1, -1, 0};
  for (int i = 0; i < 9; ++i) {
    for (int j = 0; j < 3; ++j) {
      s.control_points.push_back(engine::Vec3(r[j] * cx[i], r[j] * cy[i], z[j]));
      s.weights.push_back(i % 2 == 1 ? h : 1.0);
    }
  }
  engine::Model m;
  m.units = "mm";
  m.surfaces.push_back(std::move(s));
  return m;
}

}  // namespace nurbsreg::registration::testing
