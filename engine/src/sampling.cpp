#include "nurbsreg/engine/sampling.hpp"

#include <algorithm>
#include <numeric>
#include <random>

#include "nurbsreg/engine/decompose.hpp"

namespace nurbsreg::engine {
namespace {

constexpr int kCells = 16;

struct Cell {
  int surface;
  double u0, u1, v0, v1;
};

double area_element(const NurbsSurface& s, double u, double v) {
  const SurfaceDerivatives d = s.derivatives(u, v);
  return d.su.cross(d.sv).norm();
}

// Cells of every Bézier patch with their areas (2 x 2 Gauss-Legendre per cell).
void collect_cells(const Model& model, std::vector<Cell>& cells, std::vector<double>& areas) {
  const double g = 0.5 / std::sqrt(3.0);
  for (std::size_t si = 0; si < model.surfaces.size(); ++si) {
    const NurbsSurface& s = model.surfaces[si];
    for (const BezierPatch& patch : decompose(s)) {
      const double du = patch.param_u.width() / kCells;
      const double dv = patch.param_v.width() / kCells;
      for (int a = 0; a < kCells; ++a) {
        for (int b = 0; b < kCells; ++b) {
          const double u0 = patch.param_u.lo + a * du;
          const double v0 = patch.param_v.lo + b * dv;
          double area = 0.0;
          for (double x : {0.5 - g, 0.5 + g}) {
            for (double y : {0.5 - g, 0.5 + g})
              area += area_element(s, u0 + x * du, v0 + y * dv);
          }
          cells.push_back({static_cast<int>(si), u0, u0 + du, v0, v0 + dv});
          areas.push_back(0.25 * area * du * dv);
        }
      }
    }
  }
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
  std::vector<Cell> cells;
  std::vector<double> areas;
  collect_cells(model, cells, areas);
  std::vector<SurfaceSample> samples;
  if (cells.empty() || count == 0) return samples;
  std::vector<double> cdf(areas.size());
  std::partial_sum(areas.begin(), areas.end(), cdf.begin());
  const double total = cdf.back();
  std::mt19937_64 rng(seed);
  auto unit = [&rng] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  samples.reserve(count);
  for (std::size_t k = 0; k < count; ++k) {
    const double target = unit() * total;
    const auto it = std::upper_bound(cdf.begin(), cdf.end(), target);
    const Cell& c = cells[std::min<std::size_t>(it - cdf.begin(), cells.size() - 1)];
    SurfaceSample s;
    s.surface = c.surface;
    s.u = c.u0 + unit() * (c.u1 - c.u0);
    s.v = c.v0 + unit() * (c.v1 - c.v0);
    const NurbsSurface& surface = model.surfaces[c.surface];
    s.point = surface.evaluate(s.u, s.v);
    s.normal = surface_normal(surface, s.u, s.v);
    samples.push_back(s);
  }
  return samples;
}

double surface_area(const Model& model) {
  std::vector<Cell> cells;
  std::vector<double> areas;
  collect_cells(model, cells, areas);
  double total = 0.0;
  for (double a : areas)
    total += a;
  return total;
}

}  // namespace nurbsreg::engine
