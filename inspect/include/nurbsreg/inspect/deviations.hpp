#pragma once
// The per-point deviations an inspection is made of: every scan point that has an exact foot on
// the model, in model coordinates, with its signed distance (> 0 on the face's outer side:
// engine::ProjectionResults::signed_distance), face and parameters; and the counts of the points
// that are not there (NaN/inf coordinates in the file, no foot on the model), so that every
// report can say how many points it does not speak for.

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::inspect {

struct PointDeviations {
  std::vector<engine::Vec3> points;  // aligned scan points (model coordinates)
  std::vector<double> signed_distance;
  std::vector<std::int32_t> face;           // surface index in the model
  std::vector<double> u, v;                 // foot parameters on that surface
  std::vector<std::uint64_t> source_index;  // 0-based position of the point in the scan file
  std::size_t skipped_nonfinite = 0;        // file points with a NaN or infinite coordinate
  std::size_t unprojected = 0;              // points without a foot (projection status not ok)
  // Points farther than `exclusion_distance` from the model, left out of the inspection on
  // request (clutter: a fixture, another object); 0 when nothing is excluded by distance.
  std::size_t excluded = 0;
  double exclusion_distance = 0.0;

  std::size_t size() const { return points.size(); }
};

// The points of `aligned` whose projection status is ok, in order. `projections` has one entry
// per aligned point (signed_distance, entity, u, v, status); `source_index` is empty (then the
// position in `aligned`) or one per aligned point. Allocates the output arrays once.
PointDeviations collect_deviations(std::span<const engine::Vec3> aligned,
                                   const engine::ProjectionResults& projections,
                                   std::span<const std::uint64_t> source_index,
                                   std::size_t skipped_nonfinite);

// Leaves out the points whose |signed distance| exceeds `distance` (> 0), in place, keeping the
// order of the others, and counts them in `excluded`.
void exclude_beyond(PointDeviations& deviations, double distance);

// The fraction of the points whose |signed distance| exceeds `distance`.
double fraction_beyond(const PointDeviations& deviations, double distance);

}  // namespace nurbsreg::inspect
