#pragma once
// The benchmark's models and point sets, generated procedurally and deterministically (fixed
// seeds), so every peer sees the same geometry and the same points in the same run.

#include <cstdint>
#include <string>
#include <vector>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::bench {

struct BenchModel {
  std::string name;         // short key used on the command line: panel49, panel1369, ...
  std::string description;  // one line for the table header
  engine::Model model;
};

// Smooth freeform bicubic panel about 100 x 100 mm: 10 x 10 control points (7 x 7 = 49 Bézier
// patches) or 40 x 40 (37 x 37 = 1,369 patches), uniform clamped knots.
BenchModel make_panel(int control_points_per_side);
// The exact rational sphere of radius 50 mm (engine::make_sphere: poles and a seam).
BenchModel make_sphere_model();
// A bicubic sheet 100 x 60 mm folded back over itself with a 2 mm gap between the layers
// (12 x 8 control points, 9 x 5 = 45 patches): points between the layers have two nearly
// equidistant candidates on different layers.
BenchModel make_folded();

// All models, in table order.
std::vector<BenchModel> all_models();

// Axis-aligned bounds of a dense parameter-grid sampling of every surface.
struct Box {
  engine::Vec3 lo;
  engine::Vec3 hi;
  double diagonal() const { return (hi - lo).norm(); }
};
Box sample_bounds(const engine::Model& model);

// The points of one run. Even indices lie near the surface (an area-uniform surface sample
// moved along the normal by a uniform offset in [-2 %, 2 %] of the diagonal), odd indices
// anywhere in the bounding box enlarged by 25 % of its extent on every side. Every prefix is a
// representative subset, so slow peers run on a prefix of the same points.
//   base:     the points "before", whose feet serve as warm-start hints (as in ICP);
//   measured: base + a perturbation of exactly `perturbation` mm in a random direction.
struct PointSet {
  std::vector<engine::Vec3> base;
  std::vector<engine::Vec3> measured;
};
PointSet make_points(const engine::Model& model, const Box& box, std::size_t count,
                     double perturbation, std::uint64_t seed);

}  // namespace nurbsreg::bench
