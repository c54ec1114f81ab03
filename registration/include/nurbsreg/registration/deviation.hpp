#pragma once
// Order statistics of point-to-model distances: what `align` prints and reports as the
// deviation of an aligned scan.

#include <cstddef>
#include <vector>

namespace nurbsreg::registration {

struct DeviationSummary {
  std::size_t count = 0;  // distances summarised
  double mean = 0, rms = 0, p50 = 0, p95 = 0, p99 = 0, max = 0;
  // The distance the summarised points are within (the alignment's max correspondence
  // distance; 0 when not set): points farther away (clutter, outliers) are not summarised.
  double within = 0;
};

// The summary of `distances` (taken by value: reordered by selection). Empty input gives all
// zeros. Quantile q is the element at index floor(q * (n - 1)) of the sorted values.
DeviationSummary summarise_deviations(std::vector<double> distances);

}  // namespace nurbsreg::registration
