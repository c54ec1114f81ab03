#pragma once
// Brute-force closest points, the benchmark's oracle. Deliberately independent of every
// projector it judges (nurbsreg's included): it uses only NURBS evaluation (The NURBS Book
// A3.6/A4.4 through engine::NurbsSurface::derivatives) plus
//   1. a dense grid of parameter cells per surface (at least ~96 cells per direction and every
//      knot span split), each bounded by the box and the normal slab of a 5 x 5 sample grid,
//      both inflated by the bilinear interpolation error bound (h_u^2 |S_uu| + h_v^2 |S_vv|)/8,
//      taken 1.5 times over the sampled second derivatives;
//   2. a best-first search over blocks of cells by box distance, and in every cell whose box
//      can still beat the best distance, a box-constrained Newton polish of |S(u,v) - p|^2
//      inside that cell (projected Newton with a Gauss-Newton fallback and a backtracking
//      line search).
// The sampled second-derivative bound is a heuristic, not a proof: the driver therefore
// checks the oracle against the sphere's analytic distance and counts every answer of any
// method that beats it (should be 0).
//
// Construction allocates; compute() is const and runs a tbb::parallel_for in the caller's arena.

#include <cstdint>
#include <span>
#include <vector>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::bench {

struct ReferenceFoot {
  double distance = 0.0;
  int surface = -1;
  double u = 0.0;
  double v = 0.0;
  // The foot lies on the boundary of its surface's parameter domain (an edge, a corner, or on
  // a closed surface its seam or pole): orthogonal-projection methods need not find it.
  bool on_boundary = false;
};

class Reference {
 public:
  explicit Reference(const engine::Model& model);

  std::vector<ReferenceFoot> compute(std::span<const engine::Vec3> points) const;
  ReferenceFoot compute_one(const engine::Vec3& p) const;

  std::size_t cell_count() const { return cells_.size(); }

 private:
  struct Cell {
    engine::Vec3 lo, hi;
    // Slab around the cell: every point q of the cell has slab_lo <= normal.(q - center) <=
    // slab_hi. Far tighter than the axis-aligned box on curved surfaces seen from inside
    // (a point near a sphere's centre); normal = 0 where it is undefined (a pole).
    engine::Vec3 center, normal;
    double slab_lo, slab_hi;
    double u0, u1, v0, v1;
    int surface;
  };
  double cell_bound(const Cell& cell, const engine::Vec3& p) const;
  struct Block {
    engine::Vec3 lo, hi;
    std::vector<std::uint32_t> cells;
  };
  struct Candidate {
    double bound;
    std::uint32_t index;
  };
  struct Scratch {
    std::vector<Candidate> blocks;
    std::vector<Candidate> cells;
  };

  ReferenceFoot search(const engine::Vec3& p, Scratch& scratch) const;
  // Minimises |S - p|^2 over the cell; returns the squared distance and writes (u, v).
  double polish(const Cell& cell, const engine::Vec3& p, double& u, double& v) const;

  const engine::Model& model_;
  std::vector<Cell> cells_;
  std::vector<Block> blocks_;
};

}  // namespace nurbsreg::bench
