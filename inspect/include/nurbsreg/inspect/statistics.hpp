#pragma once
// Deviation statistics of an inspection, overall and per face, on every inspected point (never a
// subsample).
//
// Definitions (what inspect.json, the CSV and the report print):
//  - inside: lower <= d <= upper (the band's edges are inside); below: d < lower; above: d > upper.
//  - mean, min, max over the points; std the sample standard deviation (n - 1; 0 for one point);
//    rms = sqrt(mean of d^2).
//  - p5, p95: linear interpolation between order statistics, value at rank q (n - 1) of the
//    sorted values (numpy.percentile's default, "type 7").
//  - A face without points has points = 0 and NaN for every other number (null in JSON).
// Deterministic (serial sums in point order). Allocates O(points) scratch once per call.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "nurbsreg/engine/model.hpp"
#include "nurbsreg/inspect/deviations.hpp"

namespace nurbsreg::inspect {

// The tolerance band of the signed deviation, in model units: lower < upper.
struct Tolerance {
  double lower = -0.1;
  double upper = 0.1;

  bool inside(double d) const { return d >= lower && d <= upper; }
  // An error naming the option (`--tolerance-lower ...`), or nothing: both finite, lower < upper.
  std::optional<std::string> validate() const;
};

struct DeviationStats {
  std::size_t points = 0;
  std::size_t inside = 0, below = 0, above = 0;
  double mean = 0, std = 0, rms = 0, min = 0, max = 0, p5 = 0, p95 = 0;
  double inside_fraction() const;  // inside / points; NaN without points
};

struct FaceStats {
  int face = -1;
  std::string name;
  DeviationStats stats;
};

// Counts of signed deviations in equal bins over [low, high), plus the points below low and at
// or above high.
struct Histogram {
  double low = 0, high = 0;
  std::vector<std::size_t> counts;
  std::size_t under = 0, over = 0;
  double bin_width() const { return (high - low) / static_cast<double>(counts.size()); }
};

struct InspectionStatistics {
  Tolerance tolerance;
  DeviationStats overall;
  std::vector<FaceStats> faces;  // one per model surface, in model order
  Histogram histogram;
  std::size_t skipped_nonfinite = 0;
  std::size_t unprojected = 0;
  std::size_t excluded = 0;         // farther than exclusion_distance (PointDeviations)
  double exclusion_distance = 0.0;  // 0: nothing excluded by distance
};

// The statistics of the `values` (reordered: they are scratch).
DeviationStats deviation_stats(std::span<double> values, const Tolerance& tolerance);

// Everything above for `deviations` on `model`; the histogram has `bins` bins over
// [histogram_low, histogram_high) (low < high, bins > 0).
InspectionStatistics compute_statistics(const PointDeviations& deviations,
                                        const engine::Model& model, const Tolerance& tolerance,
                                        double histogram_low, double histogram_high, int bins);

}  // namespace nurbsreg::inspect
