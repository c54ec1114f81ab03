#pragma once
// One ModelCorrespondenceFinder query of test points, every answer checked against a cold
// projection of the same points (the finder's hints and borrowed certificates may change the
// work, never the answer). Shared by the finder's hint and borrow tests.

#include <gtest/gtest.h>

#include <cstddef>
#include <vector>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/icp/model_finder.hpp"

namespace nurbsreg::icp {

// The finder's counters for the query; `foot_tolerance` > 0 checks the feet too.
inline engine::ProjectionCounters find_checked(
    ModelCorrespondenceFinder& finder, engine::Projector& reference, double distance_tolerance,
    const std::vector<std::size_t>& ids, const std::vector<engine::Vec3>& points,
    double expected_motion, double foot_tolerance = 0.0, int later_queries = 0) {
  CorrespondenceQuery query;
  query.later_queries = later_queries;
  query.points = points;
  query.scan_indices = ids;
  query.expected_motion = expected_motion;
  std::vector<Correspondence> out(points.size());
  finder.find(query, out);
  engine::ProjectionResults cold;
  reference.project(engine::PointView::of(points), {}, cold);
  for (std::size_t k = 0; k < points.size(); ++k) {
    EXPECT_TRUE(out[k].valid) << k;
    EXPECT_NEAR(out[k].distance, cold.distance[k], distance_tolerance) << k;
    if (foot_tolerance > 0.0) {
      EXPECT_LT((out[k].foot - cold.foot[k]).norm(), foot_tolerance) << k;
    }
  }
  return finder.last_counters();
}

}  // namespace nurbsreg::icp
