#include "nurbsreg/inspect/clutter.hpp"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>

namespace nurbsreg::inspect {
namespace {

double band_reach(const Tolerance& band) {
  return std::max(std::abs(band.lower), std::abs(band.upper));
}

}  // namespace

std::optional<std::string> validate_exclusion(double distance, const Tolerance& band,
                                              const std::string& option) {
  if (!std::isfinite(distance) || !(distance > band_reach(band))) {
    return fmt::format(
        "{}: must be a distance beyond the tolerance band [{:+g}, {:+g}] (got {}): points "
        "inside or near the band are deviations, not clutter",
        option, band.lower, band.upper, distance);
  }
  return std::nullopt;
}

std::optional<std::string> clutter_hint(const PointDeviations& deviations, const Tolerance& band,
                                        double min_inside, const std::string& option) {
  if (deviations.exclusion_distance > 0.0 || deviations.size() == 0) return std::nullopt;
  const double far = 10.0 * band_reach(band);
  const double fraction = fraction_beyond(deviations, far);
  if (fraction <= 1.0 - min_inside || fraction == 0.0) return std::nullopt;
  return fmt::format(
      "{:.1f}% of the inspected points lie farther than {:g} (10 x the tolerance) from the "
      "model, enough to decide the verdict alone; if they are clutter (a fixture, another "
      "object), {}={:g} leaves them out, counted",
      100.0 * fraction, far, option, far);
}

}  // namespace nurbsreg::inspect
