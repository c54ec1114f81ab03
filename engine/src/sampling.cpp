#include "nurbsreg/engine/sampling.hpp"

#include <algorithm>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>

#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/trim_region.hpp"

namespace nurbsreg::engine {
namespace {

constexpr int kCells = 16;

struct Cell {
  int surface;
  double u0, u1, v0, v1;
  // The face's region when a trim loop may cross the cell (its points are then kept only when
  // inside); null when the whole cell belongs to the face.
  const TrimRegion* region;
};

double area_element(const NurbsSurface& s, double u, double v) {
  const SurfaceDerivatives d = s.derivatives(u, v);
  return d.su.cross(d.sv).norm();
}

// Cells of every Bézier patch with their areas (2 x 2 Gauss-Legendre per cell). A trimmed face
// keeps only the cells its region may meet (TrimRegion::classify); `regions` holds the regions
// the cells point to (reserved up front: the pointers stay valid).
void collect_cells(const Model& model, std::vector<TrimRegion>& regions, std::vector<Cell>& cells,
                   std::vector<double>& areas) {
  const double g = 0.5 / std::sqrt(3.0);
  regions.reserve(model.surfaces.size());
  for (std::size_t si = 0; si < model.surfaces.size(); ++si) {
    const NurbsSurface& s = model.surfaces[si];
    const TrimRegion* region = nullptr;
    if (!s.trim_loops.empty()) region = &regions.emplace_back(s);
    for (const BezierPatch& patch : decompose(s)) {
      const double du = patch.param_u.width() / kCells;
      const double dv = patch.param_v.width() / kCells;
      for (int a = 0; a < kCells; ++a) {
        for (int b = 0; b < kCells; ++b) {
          const double u0 = patch.param_u.lo + a * du;
          const double v0 = patch.param_v.lo + b * dv;
          const RegionClass in_face =
              region == nullptr ? RegionClass::inside : region->classify(u0, u0 + du, v0, v0 + dv);
          if (in_face == RegionClass::outside) continue;
          double area = 0.0;
          for (double x : {0.5 - g, 0.5 + g}) {
            for (double y : {0.5 - g, 0.5 + g})
              area += area_element(s, u0 + x * du, v0 + y * dv);
          }
          cells.push_back({static_cast<int>(si), u0, u0 + du, v0, v0 + dv,
                           in_face == RegionClass::boundary ? region : nullptr});
          areas.push_back(0.25 * area * du * dv);
        }
      }
    }
  }
}

// The share of a cell inside its face: 1 for a cell wholly inside, else the fraction of an
// 8 x 8 grid of its points that the region contains.
double inside_fraction(const Cell& c) {
  if (c.region == nullptr) return 1.0;
  constexpr int kGrid = 8;
  int inside = 0;
  for (int a = 0; a < kGrid; ++a) {
    for (int b = 0; b < kGrid; ++b) {
      inside += c.region->contains(c.u0 + (a + 0.5) / kGrid * (c.u1 - c.u0),
                                   c.v0 + (b + 0.5) / kGrid * (c.v1 - c.v0));
    }
  }
  return static_cast<double>(inside) / (kGrid * kGrid);
}

}  // namespace

Vec3 surface_normal(const NurbsSurface& surface, double u, double v) {
  const SurfaceDerivatives d = surface.derivatives(u, v);
  Vec3 n = d.su.cross(d.sv);
  const double scale = d.su.norm() * d.sv.norm();
  if (n.norm() > 1e-12 * scale && scale > 0.0) return n.normalized();
  // Degenerate point: step towards the domain centre until the normal is defined.
  const ParamInterval du = surface.domain_u();
  const ParamInterval dv = surface.domain_v();
  const double cu = 0.5 * (du.lo + du.hi);
  const double cv = 0.5 * (dv.lo + dv.hi);
  for (double step = 1e-7; step < 0.1; step *= 10.0) {
    const double uu = u + step * (cu - u) + step * 1e-3 * du.width();
    const double vv = v + step * (cv - v) + step * 1e-3 * dv.width();
    const SurfaceDerivatives e = surface.derivatives(uu, vv);
    n = e.su.cross(e.sv);
    if (n.norm() > 1e-12 * e.su.norm() * e.sv.norm() && n.norm() > 0.0) return n.normalized();
  }
  return Vec3::UnitZ();
}

std::vector<SurfaceSample> sample_surfaces(const Model& model, std::size_t count,
                                           std::uint64_t seed) {
  std::vector<TrimRegion> regions;
  std::vector<Cell> cells;
  std::vector<double> areas;
  collect_cells(model, regions, cells, areas);
  std::vector<SurfaceSample> samples;
  if (count == 0) return samples;
  if (cells.empty()) {
    throw std::runtime_error("sample_surfaces: the model has no surface area to sample");
  }
  std::vector<double> cdf(areas.size());
  std::partial_sum(areas.begin(), areas.end(), cdf.begin());
  const double total = cdf.back();
  std::mt19937_64 rng(seed);
  auto unit = [&rng] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  samples.reserve(count);
  // Rejection keeps the samples uniform over the faces: a point drawn in a cell that a trim loop
  // crosses is kept only inside the region, otherwise the whole draw starts again. Only those
  // cells reject, so a face with area accepts most draws; the cap stops a model whose trimmed
  // faces have (next to) no area.
  const std::size_t max_draws = 1000 * count + 100000;
  std::size_t draws = 0;
  while (samples.size() < count) {
    if (++draws > max_draws) {
      throw std::runtime_error(
          "sample_surfaces: the model's trimmed faces have too little area to sample (" +
          std::to_string(samples.size()) + " of " + std::to_string(count) + " points after " +
          std::to_string(max_draws) + " draws)");
    }
    const double target = unit() * total;
    const auto it = std::upper_bound(cdf.begin(), cdf.end(), target);
    const Cell& c = cells[std::min<std::size_t>(it - cdf.begin(), cells.size() - 1)];
    SurfaceSample s;
    s.surface = c.surface;
    s.u = c.u0 + unit() * (c.u1 - c.u0);
    s.v = c.v0 + unit() * (c.v1 - c.v0);
    if (c.region != nullptr && !c.region->contains(s.u, s.v)) continue;
    const NurbsSurface& surface = model.surfaces[c.surface];
    s.point = surface.evaluate(s.u, s.v);
    // The face's outer side, as the projector reports it (a reversed face's is -(S_u x S_v)).
    s.normal = surface_normal(surface, s.u, s.v);
    if (surface.reversed) s.normal = -s.normal;
    samples.push_back(s);
  }
  return samples;
}

double surface_area(const Model& model) {
  std::vector<TrimRegion> regions;
  std::vector<Cell> cells;
  std::vector<double> areas;
  collect_cells(model, regions, cells, areas);
  double total = 0.0;
  for (std::size_t k = 0; k < cells.size(); ++k)
    total += areas[k] * inside_fraction(cells[k]);
  return total;
}

}  // namespace nurbsreg::engine
