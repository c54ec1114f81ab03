#include "nurbsreg/registration/scan_size.hpp"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "nurbsreg/engine/point_extent.hpp"

namespace nurbsreg::registration {

double scan_diagonal(engine::PointView scan) {
  return engine::trimmed_box(scan).diagonal();
}

ScanSize scan_size(std::span<const engine::Vec3> scan, const engine::PreparedModel& model) {
  return {scan_diagonal(engine::PointView::of(scan)), model_size(model), model.model().units};
}

double model_size(const engine::PreparedModel& model) {
  return model.geometry_bounds().box.diagonal();
}

namespace {
std::string times(double x) {
  return fmt::format("{:.{}f}", x, x >= 10.0 ? 0 : 1);
}
}  // namespace

std::optional<std::string> far_from_model_note(std::span<const double> distances, double model_size,
                                               const std::string& units) {
  if (!(model_size > 0.0) || distances.empty()) return std::nullopt;
  const std::size_t stride = (distances.size() + kFarSample - 1) / kFarSample;
  std::vector<double> sample;
  sample.reserve(distances.size() / stride + 1);
  for (std::size_t i = 0; i < distances.size(); i += stride) {
    if (std::isfinite(distances[i])) sample.push_back(distances[i]);
  }
  if (sample.empty()) return std::nullopt;
  const auto middle = sample.begin() + static_cast<std::ptrdiff_t>(sample.size() / 2);
  std::nth_element(sample.begin(), middle, sample.end());
  const double median = *middle;
  if (!(median > model_size)) return std::nullopt;
  return fmt::format(
      "half of the points lie {:.4g} {} or more from the model, {} times its size (its "
      "bounding-box diagonal {:.4g} {}): is the scan in the model's frame? `nurbsreg align` "
      "finds the pose; is it a scan of this part?",
      median, units, times(median / model_size), model_size, units);
}

std::optional<std::string> ScanSize::note(double smaller, double larger) const {
  if (!(scan > 0.0) || !(model > 0.0)) return std::nullopt;
  const double ratio = scan / model;
  if (ratio >= smaller && ratio <= larger) return std::nullopt;
  const std::string diagonals =
      fmt::format("(bounding-box diagonals {:.4g} and {:.4g} {})", scan, model, units);
  if (ratio > larger) {
    return fmt::format(
        "the scan is {} times the size of the model {}: are both in the same units (m, mm, in)? "
        "Or does the scan hold more than the part?",
        times(ratio), diagonals);
  }
  return fmt::format(
      "the scan is 1/{} of the size of the model {}: are both in the same units (m, mm, in)?",
      times(1.0 / ratio), diagonals);
}

std::string ScanSize::with_failure_note(std::string failure) const {
  const std::optional<std::string> size_note = failure_note();
  if (!size_note) return failure;
  constexpr double kUnitsApart = 20.0;
  const double ratio = scan / model;
  const std::size_t lead = failure.find(": ");
  if ((ratio >= kUnitsApart || ratio <= 1.0 / kUnitsApart) && lead != std::string::npos) {
    failure.insert(lead + 2, *size_note + "; ");
    return failure;
  }
  return failure + "; " + *size_note;
}

}  // namespace nurbsreg::registration
