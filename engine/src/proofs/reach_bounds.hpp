#pragma once
// Internal: PreparedModel's reach bounds: the cells (PreparedModel::ReachCell), their lookup
// (reach_cell, inline: the projection's hot path) and their construction (reach_bounds.cpp).

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <mutex>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"

namespace nurbsreg::engine {

// For a foot f on an untrimmed polynomial surface, a lower bound rho of how far a point may lie
// from f along a direction of f's normal cone and still have f as its closest point on the whole
// model (the cut distance of Federer's reach: the open ball of radius rho touching the model at f
// on that side holds no model point). A query q whose KKT point f on the surface has
// |q - f| < rho is then answered without any search. One ReachCell per cell of a k x k grid
// (reach_cells_per_side) of each such patch's local (s, t) square; each bound holds for every
// foot of its (closed) cell:
//   plus / minus: q on the side of n = S_u x S_v / minus n (an orthogonal foot);
//   boundary: directions of the normal cone at a foot on the surface's own edge or corner
//   (cos th n + sin th m, m in the outward tangential cone), by sectors of th in [0, pi]; 0
//   for a cell that does not touch the surface's edge.
// Floats rounded down. 0 where nothing is proven (a cell touching another part of the model, a
// seam, a pole, a crease).
struct PreparedModel::ReachCell {
  float plus = 0.0f, minus = 0.0f;
  // Boundary feet, by the angle th of the direction from n: sector k holds th in
  // [k, k + 1] pi / kReachSectors (th = pi / 2: straight out of the surface's edge).
  float boundary[kReachSectors] = {};
};

// Shared by copies of a PreparedModel; written once under `once`, then read-only.
struct PreparedModel::ReachState {
  std::once_flag once;
  std::atomic<bool> ready{false};
  std::vector<std::uint32_t> first;  // per patch: its first ReachCell, or kNoReach
  std::vector<ReachCell> cells;
  int k = 1;
};

inline const PreparedModel::ReachCell* PreparedModel::reach_cell(std::size_t i, double s,
                                                                 double t) const {
  const ReachState& r = *reach_;
  if (!r.ready.load(std::memory_order_acquire)) return nullptr;
  const std::uint32_t first = r.first[i];
  if (first == kNoReach) return nullptr;
  const int a = std::clamp(static_cast<int>(s * r.k), 0, r.k - 1);
  const int b = std::clamp(static_cast<int>(t * r.k), 0, r.k - 1);
  return &r.cells[first + static_cast<std::uint32_t>(a * r.k + b)];
}

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
