#include "scan_shape.hpp"

#include <spdlog/fmt/fmt.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace nurbsreg::registration::detail {

std::optional<std::string> flat_scan_note(std::span<const engine::Vec3> scan, double noise) {
  if (scan.size() < 3) return std::nullopt;
  // The mean first, then the covariance about it (one pass would lose the spread to rounding
  // for a scan far from the origin).
  engine::Vec3 mean = engine::Vec3::Zero();
  for (const engine::Vec3& p : scan)
    mean += p;
  mean /= static_cast<double>(scan.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const engine::Vec3& p : scan) {
    const engine::Vec3 d = p - mean;
    covariance.noalias() += d * d.transpose();
  }
  covariance /= static_cast<double>(scan.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  if (solver.info() != Eigen::Success) return std::nullopt;
  // Ascending: the spread off the principal plane, off the principal line, along it (rms).
  const engine::Vec3 spread = solver.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  // A noise-free flat scan has a noise estimate of 0 and a spread off its plane at the rounding
  // of the smallest eigenvalue: about eps times the largest, so its root about 1e-8 of the
  // scan's extent (1e-6 leaves room for any compiler's sums).
  const double flat = 2.0 * std::max(noise, 1e-6 * spread.z());
  // Across: an evenly filled square of side a has an rms spread of a / sqrt(12) along each side.
  const auto across = [](double rms) { return std::sqrt(12.0) * rms; };
  if (spread.y() <= flat) {
    return fmt::format(
        "the scan is a line: its points lie {:.3g} rms off one line, no more than twice its "
        "noise ({:.3g}), about {:.3g} long: it fits every straight edge of the model, anywhere "
        "along it "
        "and at any turn about it",
        spread.y(), noise, across(spread.z()));
  }
  if (spread.x() <= flat) {
    return fmt::format(
        "the scan is flat: its points lie {:.3g} rms off one plane, no more than twice its "
        "noise ({:.3g}), about {:.3g} x {:.3g} across: it fits every flat face of the model large "
        "enough, anywhere on it and at any turn about its normal (from a starting pose the "
        "report names the directions it leaves free)",
        spread.x(), noise, across(spread.z()), across(spread.y()));
  }
  return std::nullopt;
}

}  // namespace nurbsreg::registration::detail
