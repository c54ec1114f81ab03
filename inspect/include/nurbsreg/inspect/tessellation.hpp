#pragma once
// A display mesh of the model's faces (the report's grey model beside the coloured scan, and
// the PNG's background): each surface evaluated on a regular (u, v) grid, a few samples per knot
// span, two triangles per grid cell; on a trimmed face only the cells whose centre lies in the
// trimmed region (so its outline is accurate to a grid cell). For looking at, not for measuring:
// every deviation comes from the exact projection. Parallel over surfaces (TBB), deterministic
// output order; allocates.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"

namespace nurbsreg::inspect {

struct DisplayMesh {
  std::vector<float> positions;          // 3 per vertex
  std::vector<std::uint32_t> triangles;  // 3 vertex indices per triangle
  std::size_t vertex_count() const { return positions.size() / 3; }
  std::size_t triangle_count() const { return triangles.size() / 3; }
};

// At most about `max_vertices` vertices over all surfaces (the grid density is lowered evenly
// when the model has many faces).
DisplayMesh tessellate(const engine::PreparedModel& model, std::size_t max_vertices);

}  // namespace nurbsreg::inspect
