#pragma once
// The sizes (bounding-box diagonals) of a scan and of the model, to tell the user when they are
// far apart: a scan in metres against a model in millimetres is 1/1000 of it, and ICP then
// "aligns" it onto a small patch of the model with a tiny rms; a scan in inches is 1/25.4; a
// scan of a whole scene is much larger than its part.

#include <optional>
#include <span>
#include <string>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::registration {

struct ScanSize {
  double scan = 0.0;
  double model = 0.0;
  std::string units;  // the model's

  // One line when scan / model lies outside [smaller, larger]; nothing otherwise, or when either
  // has no size (a single point).
  std::optional<std::string> note(double smaller, double larger) const;
  // The warning of every command: partial views of large models stay quiet down to 1/200.
  std::optional<std::string> warning() const { return note(1.0 / 200.0, 8.0); }
  // Added to a failed alignment's message, where a mismatch is the likelier cause: 1/10 and 4.
  std::optional<std::string> failure_note() const { return note(0.1, 4.0); }
  // `failure` with failure_note() added: after it, or, when the sizes differ as units do (20
  // times or more: m and mm, mm and in), first after its lead ("alignment failed: ", "poor fit:
  // "), since nothing else said there matters until the units do.
  std::string with_failure_note(std::string failure) const;
};

// The scan's size: the diagonal of its finite points' box less their extreme 0.1% on each side
// of each axis (engine::trimmed_box). A few stray points far from the rest (a scanner's glitch at
// 1e14) then neither set off the size warning nor loosen what is derived from the size (the fit
// verdict's tolerance floor, 1e-5 of it).
double scan_diagonal(engine::PointView scan);
ScanSize scan_size(std::span<const engine::Vec3> scan, const engine::PreparedModel& model);
// The model's size for these checks: the diagonal of its trimmed faces' box (a face cut from a
// large surface is as large as the face), PreparedModel::geometry_bounds.
double model_size(const engine::PreparedModel& model);

// A projection whose points mostly lie far from the model: the median distance over the finite
// `distances` is larger than the model itself (`model_size`, its diagonal). The points are then
// not a scan of the part in the model's frame (a scan still in the scanner's frame: `align`
// first; or another part), and their "deviations" say nothing about the part. One line then,
// nothing otherwise (or when no distance is finite). Clutter and outliers do not set it off while
// at least half of the points are near. The median is taken over at most 65,536 evenly spaced
// points (kFarSample): a warning's threshold, not a statistic that is reported.
inline constexpr std::size_t kFarSample = 65536;
std::optional<std::string> far_from_model_note(std::span<const double> distances, double model_size,
                                               const std::string& units);

}  // namespace nurbsreg::registration
