#include "nurbsreg/inspect/statistics.hpp"

#include <spdlog/fmt/fmt.h>
#include <algorithm>
#include <cmath>
#include <limits>

namespace nurbsreg::inspect {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// numpy.percentile's default: the value at rank q (n - 1), linear between neighbours. Reorders
// `values` (two selections).
double quantile(std::span<double> values, double q) {
  const double rank = q * static_cast<double>(values.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(rank));
  std::nth_element(values.begin(), values.begin() + lo, values.end());
  const double a = values[lo];
  if (lo + 1 >= values.size()) return a;
  // The next order statistic is the minimum of what lies above position lo.
  const double b = *std::min_element(values.begin() + lo + 1, values.end());
  return a + (rank - static_cast<double>(lo)) * (b - a);
}

}  // namespace

std::optional<std::string> Tolerance::validate() const {
  if (!std::isfinite(lower))
    return fmt::format("--tolerance-lower: must be finite (got {})", lower);
  if (!std::isfinite(upper))
    return fmt::format("--tolerance-upper: must be finite (got {})", upper);
  if (!(lower < upper)) {
    return fmt::format("tolerance: lower {} must be less than upper {}", lower, upper);
  }
  return std::nullopt;
}

double DeviationStats::inside_fraction() const {
  return points == 0 ? kNaN : static_cast<double>(inside) / static_cast<double>(points);
}

DeviationStats deviation_stats(std::span<double> values, const Tolerance& tolerance) {
  DeviationStats s;
  s.points = values.size();
  if (values.empty()) {
    s.mean = s.std = s.rms = s.min = s.max = s.p5 = s.p95 = kNaN;
    return s;
  }
  double sum = 0.0, sum_sq = 0.0;
  s.min = values[0];
  s.max = values[0];
  for (const double d : values) {
    sum += d;
    sum_sq += d * d;
    s.min = std::min(s.min, d);
    s.max = std::max(s.max, d);
    if (d < tolerance.lower) {
      ++s.below;
    } else if (d > tolerance.upper) {
      ++s.above;
    } else {
      ++s.inside;
    }
  }
  const double n = static_cast<double>(values.size());
  s.mean = sum / n;
  s.rms = std::sqrt(sum_sq / n);
  // Second pass about the mean: no cancellation when the mean is large against the spread.
  double centred = 0.0;
  for (const double d : values)
    centred += (d - s.mean) * (d - s.mean);
  s.std = values.size() > 1 ? std::sqrt(centred / (n - 1.0)) : 0.0;
  s.p5 = quantile(values, 0.05);
  s.p95 = quantile(values, 0.95);
  return s;
}

InspectionStatistics compute_statistics(const PointDeviations& deviations,
                                        const engine::Model& model, const Tolerance& tolerance,
                                        double histogram_low, double histogram_high, int bins) {
  InspectionStatistics out;
  out.tolerance = tolerance;
  out.skipped_nonfinite = deviations.skipped_nonfinite;
  out.unprojected = deviations.unprojected;
  out.excluded = deviations.excluded;
  out.exclusion_distance = deviations.exclusion_distance;
  const std::size_t n = deviations.size();
  const std::size_t faces = model.surfaces.size();

  // The values grouped by face (a counting sort): one scratch array serves every face.
  std::vector<std::size_t> start(faces + 1, 0);
  for (const std::int32_t f : deviations.face)
    ++start[static_cast<std::size_t>(f) + 1];
  for (std::size_t f = 0; f < faces; ++f)
    start[f + 1] += start[f];
  std::vector<double> grouped(n);
  {
    std::vector<std::size_t> next(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < n; ++i)
      grouped[next[static_cast<std::size_t>(deviations.face[i])]++] = deviations.signed_distance[i];
  }
  out.faces.resize(faces);
  for (std::size_t f = 0; f < faces; ++f) {
    out.faces[f].face = static_cast<int>(f);
    out.faces[f].name = model.surfaces[f].name;
    // Each face reorders its own slice of `grouped`; the overall statistics use a copy below.
    out.faces[f].stats = deviation_stats(
        std::span<double>(grouped.data() + start[f], start[f + 1] - start[f]), tolerance);
  }
  std::vector<double> all(deviations.signed_distance.begin(), deviations.signed_distance.end());
  out.overall = deviation_stats(all, tolerance);

  Histogram& h = out.histogram;
  h.low = histogram_low;
  h.high = histogram_high;
  h.counts.assign(static_cast<std::size_t>(std::max(bins, 1)), 0);
  const double scale = static_cast<double>(h.counts.size()) / (h.high - h.low);
  for (const double d : deviations.signed_distance) {
    if (d < h.low) {
      ++h.under;
    } else if (d >= h.high) {
      ++h.over;
    } else {
      const auto k = std::min(h.counts.size() - 1, static_cast<std::size_t>((d - h.low) * scale));
      ++h.counts[k];
    }
  }
  return out;
}

}  // namespace nurbsreg::inspect
