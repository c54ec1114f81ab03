#include <spdlog/fmt/fmt.h>

#include <Eigen/SVD>
#include <numbers>

#include "verdict.hpp"

namespace nurbsreg::registration::detail {

std::string describe_symmetry(const Eigen::Isometry3d& winner,
                              const Eigen::Isometry3d& alternative) {
  const Eigen::Isometry3d S = alternative * winner.inverse();
  const Eigen::AngleAxisd aa(S.linear());
  const double degrees = aa.angle() * 180.0 / std::numbers::pi;
  const engine::Vec3 t = S.translation();
  if (degrees < 1.0) {
    return fmt::format("translation by ({:.4g}, {:.4g}, {:.4g})", t.x(), t.y(), t.z());
  }
  // The axis passes through c with (I - R) c = t - (t.a) a: the least-norm solution.
  const engine::Vec3 a = aa.axis();
  const Eigen::Matrix3d M = Eigen::Matrix3d::Identity() - S.linear();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const engine::Vec3 c = svd.solve(t - t.dot(a) * a);
  const double slide = t.dot(a);
  std::string text = fmt::format(
      "rotation by {:.1f} deg about ({:.3f}, {:.3f}, {:.3f}) through ({:.4g}, {:.4g}, "
      "{:.4g})",
      degrees, a.x(), a.y(), a.z(), c.x(), c.y(), c.z());
  if (std::abs(slide) > 1e-9 * (1.0 + t.norm())) text += fmt::format(", sliding {:.4g}", slide);
  return text;
}

std::string describe_continuous_symmetry(const icp::DegeneracyReport& degeneracy) {
  std::string text;
  for (const icp::FreeDirection& f : degeneracy.free_directions) {
    const engine::Vec3& d = f.direction;
    const engine::Vec3& c = f.point;
    if (!text.empty()) text += "; ";
    if (f.kind == icp::FreeDirection::Kind::translation) {
      text +=
          fmt::format("continuous translation along ({:.3f}, {:.3f}, {:.3f})", d.x(), d.y(), d.z());
      continue;
    }
    text += fmt::format(
        "continuous rotation about ({:.3f}, {:.3f}, {:.3f}) through ({:.4g}, {:.4g}, {:.4g})",
        d.x(), d.y(), d.z(), c.x(), c.y(), c.z());
    if (f.kind == icp::FreeDirection::Kind::screw) {
      text += fmt::format(", sliding {:.4g} per radian", f.pitch);
    }
  }
  return text;
}

}  // namespace nurbsreg::registration::detail
