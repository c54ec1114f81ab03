#pragma once
// Points on a model's surfaces: area-uniform sampling and robust unit normals. Used by
// `nurbsreg synth`, the benchmarks and the tests. Sampling allocates (it is not a hot path).

#include <cstdint>
#include <vector>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::engine {

struct SurfaceSample {
  int surface = 0;
  double u = 0.0;
  double v = 0.0;
  Vec3 point = Vec3::Zero();
  // Unit normal on the face's outer side: surface_normal, flipped for a reversed face (the
  // normal the projector reports for this point).
  Vec3 normal = Vec3::UnitZ();
};

// Unit normal Su x Sv at (u, v). Where it vanishes (a pole of a collapsed edge, a cusp) the
// normal is the limit taken from a point moved slightly into the domain interior.
Vec3 surface_normal(const NurbsSurface& surface, double u, double v);

// `count` samples distributed uniformly by area over all surfaces of the model, deterministic
// for a given seed and count (the same for any number of threads: drawn in parallel, in fixed
// chunks with their own random streams). Rejection sampling: a cell of a grid per Bézier
// patch (8 x 8, quartered where a rational patch's area element varies strongly) is proposed in
// proportion to a bound of the area element |Su x Sv| over it, a point uniformly in the cell,
// and the point is kept with probability |Su x Sv| / bound. The bound is estimated from the
// element and its gradient on a 3 x 3 grid of the cell; should a sample ever exceed it, a
// warning says so (the density is then not exact there). A trimmed surface is sampled on its face
// only (the region of its trim loops, TrimRegion): draws outside it are rejected. Throws
// std::invalid_argument for trim loops a TrimRegion cannot be built from, and
// std::runtime_error when the model has no area to sample (no surfaces, trimmed faces whose
// regions are empty, or almost every draw rejected).
std::vector<SurfaceSample> sample_surfaces(const Model& model, std::size_t count,
                                           std::uint64_t seed);

// Total surface area of the model (16 x 16 cells per Bézier patch, 4-point Gauss per cell); of a
// trimmed surface, the face's: a cell a trim loop may cross counts with the fraction of an
// 8 x 8 grid of its points inside the region.
double surface_area(const Model& model);

}  // namespace nurbsreg::engine
