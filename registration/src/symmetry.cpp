#include <spdlog/fmt/fmt.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "verdict.hpp"

namespace nurbsreg::registration::detail {
namespace {

// A length to the resolution it is known to: the poses come out of an ICP, so digits below a
// fraction of the sample spacing are noise ("through (-9.4e-06, ...)" for a point at 0).
std::string length_text(double x, double resolution) {
  if (!(resolution > 0.0)) return fmt::format("{:.4g}", x);
  const double rounded = std::round(x / resolution) * resolution;
  const int decimals = std::max(0, -static_cast<int>(std::floor(std::log10(resolution))));
  return fmt::format("{:.{}f}", rounded == 0.0 ? 0.0 : rounded, decimals);
}

// A unit direction to three decimals, without "-0.000".
std::string direction_text(const engine::Vec3& d) {
  auto c = [](double x) { return std::abs(x) < 5e-4 ? 0.0 : x; };
  return fmt::format("({:.3f}, {:.3f}, {:.3f})", c(d.x()), c(d.y()), c(d.z()));
}

std::string point_text(const engine::Vec3& p, double resolution) {
  return fmt::format("({}, {}, {})", length_text(p.x(), resolution), length_text(p.y(), resolution),
                     length_text(p.z(), resolution));
}

}  // namespace

std::string describe_symmetry(const Eigen::Isometry3d& winner, const Eigen::Isometry3d& alternative,
                              double resolution) {
  const Eigen::Isometry3d S = alternative * winner.inverse();
  const Eigen::AngleAxisd aa(S.linear());
  const double degrees = aa.angle() * 180.0 / std::numbers::pi;
  const engine::Vec3 t = S.translation();
  if (degrees < 1.0) {
    return "translation by " + point_text(t, resolution);
  }
  // The axis passes through c with (I - R) c = t - (t.a) a: the least-norm solution.
  const engine::Vec3 a = aa.axis();
  const Eigen::Matrix3d M = Eigen::Matrix3d::Identity() - S.linear();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const engine::Vec3 c = svd.solve(t - t.dot(a) * a);
  const double slide = t.dot(a);
  std::string text = fmt::format("rotation by {:.1f} deg about {} through {}", degrees,
                                 direction_text(a), point_text(c, resolution));
  if (std::abs(slide) >= 0.5 * resolution) {
    text += ", sliding " + length_text(slide, resolution);
  }
  return text;
}

std::string describe_continuous_symmetry(const icp::DegeneracyReport& degeneracy,
                                         double resolution) {
  std::string text;
  for (const icp::FreeDirection& f : degeneracy.free_directions) {
    const engine::Vec3& d = f.direction;
    const engine::Vec3& c = f.point;
    if (!text.empty()) text += "; ";
    if (f.kind == icp::FreeDirection::Kind::translation) {
      text += "continuous translation along " + direction_text(d);
      continue;
    }
    text +=
        "continuous rotation about " + direction_text(d) + " through " + point_text(c, resolution);
    if (f.kind == icp::FreeDirection::Kind::screw) {
      text += ", sliding " + length_text(f.pitch, resolution) + " per radian";
    }
  }
  return text;
}

}  // namespace nurbsreg::registration::detail
