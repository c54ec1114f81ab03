#include "nurbsreg/inspect/deviations.hpp"

#include <cassert>
#include <cmath>

namespace nurbsreg::inspect {

PointDeviations collect_deviations(std::span<const engine::Vec3> aligned,
                                   const engine::ProjectionResults& projections,
                                   std::span<const std::uint64_t> source_index,
                                   std::size_t skipped_nonfinite) {
  assert(projections.size() == aligned.size());
  assert(source_index.empty() || source_index.size() == aligned.size());
  PointDeviations out;
  out.skipped_nonfinite = skipped_nonfinite;
  std::size_t kept = 0;
  for (std::size_t i = 0; i < aligned.size(); ++i)
    kept += projections.status[i] == engine::ProjectionStatus::ok;
  out.points.reserve(kept);
  out.signed_distance.reserve(kept);
  out.face.reserve(kept);
  out.u.reserve(kept);
  out.v.reserve(kept);
  out.source_index.reserve(kept);
  for (std::size_t i = 0; i < aligned.size(); ++i) {
    if (projections.status[i] != engine::ProjectionStatus::ok) continue;
    out.points.push_back(aligned[i]);
    out.signed_distance.push_back(projections.signed_distance[i]);
    out.face.push_back(projections.entity[i]);
    out.u.push_back(projections.u[i]);
    out.v.push_back(projections.v[i]);
    out.source_index.push_back(source_index.empty() ? i : source_index[i]);
  }
  out.unprojected = aligned.size() - kept;
  return out;
}

void exclude_beyond(PointDeviations& d, double distance) {
  assert(distance > 0.0);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (!(std::abs(d.signed_distance[i]) <= distance)) continue;
    d.points[kept] = d.points[i];
    d.signed_distance[kept] = d.signed_distance[i];
    d.face[kept] = d.face[i];
    d.u[kept] = d.u[i];
    d.v[kept] = d.v[i];
    d.source_index[kept] = d.source_index[i];
    ++kept;
  }
  d.excluded += d.size() - kept;
  d.exclusion_distance = distance;
  d.points.resize(kept);
  d.signed_distance.resize(kept);
  d.face.resize(kept);
  d.u.resize(kept);
  d.v.resize(kept);
  d.source_index.resize(kept);
}

double fraction_beyond(const PointDeviations& d, double distance) {
  if (d.size() == 0) return 0.0;
  std::size_t far = 0;
  for (const double s : d.signed_distance)
    far += std::abs(s) > distance;
  return static_cast<double>(far) / static_cast<double>(d.size());
}

}  // namespace nurbsreg::inspect
