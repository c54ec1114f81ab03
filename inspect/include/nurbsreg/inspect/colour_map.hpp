#pragma once
// The deviation colour map: diverging about the tolerance band, which has one neutral colour;
// graded from the band's edge to a saturation limit on each side, and the end colour beyond it
// (saturated, so a few far outliers do not wash out the scale). The same map colours the PLY,
// the PNG and the HTML viewer, and the legend prints the scheme and its limits.
// Pure functions of the value: thread-safe, no allocation.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "nurbsreg/inspect/statistics.hpp"

namespace nurbsreg::inspect {

struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Rgb&) const = default;
};

enum class ColourScheme : std::uint8_t {
  // GOM/PolyWorks style: blue (below) .. cyan | green band | yellow .. red (above).
  metrology,
  // Blue .. light blue | grey band | light red .. red (prints well in grey scale).
  blue_red,
};

std::string_view to_string(ColourScheme scheme);
// "metrology" or "blue-red"; nothing otherwise.
std::optional<ColourScheme> parse_colour_scheme(std::string_view name);

struct ColourScale {
  ColourScheme scheme = ColourScheme::metrology;
  Tolerance band;
  // Saturation limits: the map reaches its end colours at these deviations (lower < band.lower,
  // upper > band.upper).
  double lower_limit = -0.3;
  double upper_limit = 0.3;

  // The default limits: three times the band's extent on each side of zero (with at least one
  // band width beyond each edge).
  static ColourScale around(const Tolerance& band, ColourScheme scheme);

  // An error naming the option (`--colour-max ...`), or nothing.
  std::optional<std::string> validate() const;
  Rgb colour(double d) const;
  Rgb band_colour() const;
};

}  // namespace nurbsreg::inspect
