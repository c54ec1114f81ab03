#pragma once
// Internal: the construction of PreparedModel's reach bounds (PreparedModel::ReachCell).

#include <cstdint>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"

namespace nurbsreg::engine {

struct ReachTable {
  std::vector<std::uint32_t> first;  // per patch: its first cell, or PreparedModel::kNoReach
  std::vector<PreparedModel::ReachCell> cells;
  int cells_per_side = 1;
};

// Bounds for every patch of every untrimmed polynomial surface of `model`, whose patches,
// surface grids and patch hierarchy must be complete (the last step of PreparedModel's
// construction). Runs the cells in parallel (TBB).
ReachTable build_reach_table(const PreparedModel& model);

}  // namespace nurbsreg::engine
