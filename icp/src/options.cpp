// Options validation, enum names and the one-line report.
#include <cmath>
#include <cstdio>
#include <sstream>

#include "nurbsreg/icp/icp.hpp"

namespace nurbsreg::icp {
namespace {

std::string got(double x) {
  std::ostringstream out;
  out << " (got " << x << ")";
  return out.str();
}

std::string normalised(std::string_view text) {
  std::string s(text);
  for (char& c : s) {
    if (c == '-') c = '_';
  }
  return s;
}

}  // namespace

std::string_view to_string(IcpMethod method) {
  switch (method) {
    case IcpMethod::point_to_plane:
      return "point-to-plane";
    case IcpMethod::point_to_point:
      return "point-to-point";
  }
  return "unknown";
}

std::string_view to_string(RobustKernel kernel) {
  switch (kernel) {
    case RobustKernel::none:
      return "none";
    case RobustKernel::huber:
      return "huber";
    case RobustKernel::tukey:
      return "tukey";
    case RobustKernel::geman_mcclure:
      return "geman-mcclure";
  }
  return "unknown";
}

std::string_view to_string(IcpTermination termination) {
  switch (termination) {
    case IcpTermination::converged:
      return "converged";
    case IcpTermination::degenerate:
      return "degenerate";
    case IcpTermination::max_iterations:
      return "max_iterations";
    case IcpTermination::too_few_correspondences:
      return "too_few_correspondences";
    case IcpTermination::invalid_input:
      return "invalid_input";
    case IcpTermination::numerical_failure:
      return "numerical_failure";
    case IcpTermination::time_limit:
      return "time_limit";
  }
  return "unknown";
}

std::optional<IcpMethod> parse_icp_method(std::string_view text) {
  const std::string s = normalised(text);
  if (s == "point_to_plane") return IcpMethod::point_to_plane;
  if (s == "point_to_point") return IcpMethod::point_to_point;
  return std::nullopt;
}

std::optional<RobustKernel> parse_robust_kernel(std::string_view text) {
  const std::string s = normalised(text);
  if (s == "none") return RobustKernel::none;
  if (s == "huber") return RobustKernel::huber;
  if (s == "tukey") return RobustKernel::tukey;
  if (s == "geman_mcclure") return RobustKernel::geman_mcclure;
  return std::nullopt;
}

std::optional<std::string> IcpOptions::validate() const {
  if (method != IcpMethod::point_to_plane && method != IcpMethod::point_to_point) {
    return "method: unknown value";
  }
  if (max_iterations < 1) return "max_iterations: must be >= 1" + got(max_iterations);
  if (!(max_correspondence_distance > 0.0)) {
    return "max_correspondence_distance: must be > 0" + got(max_correspondence_distance);
  }
  if (!(keep_fraction > 0.0 && keep_fraction <= 1.0)) {
    return "keep_fraction: must be in (0, 1]" + got(keep_fraction);
  }
  if (kernel != RobustKernel::none && kernel != RobustKernel::huber &&
      kernel != RobustKernel::tukey && kernel != RobustKernel::geman_mcclure) {
    return "kernel: unknown value";
  }
  if (!(kernel_scale >= 0.0 && std::isfinite(kernel_scale))) {
    return "kernel_scale: must be finite and >= 0 (0: automatic)" + got(kernel_scale);
  }
  for (std::size_t i = 0; i < coarse_sizes.size(); ++i) {
    if (coarse_sizes[i] < 3) {
      return "coarse_sizes[" + std::to_string(i) + "]: must be >= 3 (got " +
             std::to_string(coarse_sizes[i]) + ")";
    }
    if (i > 0 && coarse_sizes[i] <= coarse_sizes[i - 1]) {
      return "coarse_sizes[" + std::to_string(i) + "]: must be larger than the previous size";
    }
  }
  if (!(rotation_tolerance >= 0.0 && std::isfinite(rotation_tolerance))) {
    return "rotation_tolerance: must be finite and >= 0" + got(rotation_tolerance);
  }
  if (!(translation_tolerance >= 0.0 && std::isfinite(translation_tolerance))) {
    return "translation_tolerance: must be finite and >= 0" + got(translation_tolerance);
  }
  if (!(relative_rms_tolerance >= 0.0 && std::isfinite(relative_rms_tolerance))) {
    return "relative_rms_tolerance: must be finite and >= 0" + got(relative_rms_tolerance);
  }
  if (!(statistical_tolerance >= 0.0 && std::isfinite(statistical_tolerance))) {
    return "statistical_tolerance: must be finite and >= 0" + got(statistical_tolerance);
  }
  if (!(coarse_statistical_tolerance >= 0.0 && std::isfinite(coarse_statistical_tolerance))) {
    return "coarse_statistical_tolerance: must be finite and >= 0" +
           got(coarse_statistical_tolerance);
  }
  if (!(initial_expected_motion > 0.0)) {
    return "initial_expected_motion: must be > 0 (infinity: unknown)" +
           got(initial_expected_motion);
  }
  if (min_correspondences < 3) {
    return "min_correspondences: must be >= 3 (got " + std::to_string(min_correspondences) + ")";
  }
  if (!(degeneracy_threshold >= 0.0 && degeneracy_threshold < 1.0)) {
    return "degeneracy_threshold: must be in [0, 1)" + got(degeneracy_threshold);
  }
  return std::nullopt;
}

std::string IcpResult::brief_report() const {
  char numbers[160];
  std::snprintf(numbers, sizeof numbers,
                " after %d iterations (%.3g s): rms %.6g over %zu/%zu inliers", iterations, seconds,
                rms, inliers, points);
  std::string line = std::string(to_string(termination)) + numbers;
  if (degeneracy.degenerate()) line += "; free: " + degeneracy.describe();
  if (termination != IcpTermination::converged && termination != IcpTermination::degenerate &&
      !message.empty()) {
    line += "; " + message;
  }
  return line;
}

}  // namespace nurbsreg::icp
