#include "nurbsreg/inspect/colour_map.hpp"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>

namespace nurbsreg::inspect {
namespace {

// A ramp of three stops from the band's edge (t = 0) to the saturation limit (t = 1).
using Ramp = std::array<Rgb, 3>;

struct Palette {
  Rgb band;
  Ramp below, above;
};

constexpr Palette kMetrology{{70, 185, 90},
                             {{{110, 225, 255}, {20, 110, 245}, {25, 20, 160}}},
                             {{{250, 235, 60}, {250, 130, 20}, {200, 20, 30}}}};
constexpr Palette kBlueRed{{205, 205, 205},
                           {{{175, 200, 245}, {70, 120, 205}, {15, 40, 130}}},
                           {{{250, 185, 165}, {215, 85, 70}, {140, 10, 30}}}};

const Palette& palette(ColourScheme scheme) {
  return scheme == ColourScheme::blue_red ? kBlueRed : kMetrology;
}

std::uint8_t mix(std::uint8_t a, std::uint8_t b, double t) {
  return static_cast<std::uint8_t>(std::lround(a + (b - a) * t));
}

Rgb along(const Ramp& ramp, double t) {
  t = std::clamp(t, 0.0, 1.0) * 2.0;
  const int k = t < 1.0 ? 0 : 1;
  const double f = t - k;
  return {mix(ramp[k].r, ramp[k + 1].r, f), mix(ramp[k].g, ramp[k + 1].g, f),
          mix(ramp[k].b, ramp[k + 1].b, f)};
}

}  // namespace

std::string_view to_string(ColourScheme scheme) {
  return scheme == ColourScheme::blue_red ? "blue-red" : "metrology";
}

std::optional<ColourScheme> parse_colour_scheme(std::string_view name) {
  if (name == "metrology") return ColourScheme::metrology;
  if (name == "blue-red") return ColourScheme::blue_red;
  return std::nullopt;
}

ColourScale ColourScale::around(const Tolerance& band, ColourScheme scheme) {
  ColourScale scale;
  scale.scheme = scheme;
  scale.band = band;
  const double width = band.upper - band.lower;
  scale.lower_limit = std::min(3.0 * band.lower, band.lower - width);
  scale.upper_limit = std::max(3.0 * band.upper, band.upper + width);
  return scale;
}

std::optional<std::string> ColourScale::validate() const {
  if (!std::isfinite(lower_limit) || !(lower_limit < band.lower)) {
    return fmt::format("--colour-min: must be below the lower tolerance {} (got {})", band.lower,
                       lower_limit);
  }
  if (!std::isfinite(upper_limit) || !(upper_limit > band.upper)) {
    return fmt::format("--colour-max: must be above the upper tolerance {} (got {})", band.upper,
                       upper_limit);
  }
  return std::nullopt;
}

Rgb ColourScale::band_colour() const {
  return palette(scheme).band;
}

Rgb ColourScale::colour(double d) const {
  const Palette& p = palette(scheme);
  if (d < band.lower) return along(p.below, (band.lower - d) / (band.lower - lower_limit));
  if (d > band.upper) return along(p.above, (d - band.upper) / (upper_limit - band.upper));
  return p.band;
}

}  // namespace nurbsreg::inspect
