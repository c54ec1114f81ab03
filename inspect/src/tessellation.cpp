#include "nurbsreg/inspect/tessellation.hpp"
#include "nurbsreg/engine/cancellation.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace nurbsreg::inspect {
namespace {

int distinct_spans(const std::vector<double>& knots, int degree, int count) {
  int spans = 0;
  for (int i = degree; i < count; ++i)
    spans += knots[i + 1] > knots[i];
  return std::max(spans, 1);
}

struct SurfaceGrid {
  int nu = 0, nv = 0;  // samples per direction
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;  // local vertex indices
};

void sample(const engine::NurbsSurface& s, const engine::TrimRegion* region, SurfaceGrid& g) {
  const engine::ParamInterval du = s.domain_u(), dv = s.domain_v();
  const auto u_at = [&](double i) { return du.lo + (du.hi - du.lo) * i / (g.nu - 1); };
  const auto v_at = [&](double j) { return dv.lo + (dv.hi - dv.lo) * j / (g.nv - 1); };
  g.positions.resize(static_cast<std::size_t>(g.nu) * g.nv * 3);
  for (int i = 0; i < g.nu; ++i) {
    for (int j = 0; j < g.nv; ++j) {
      const engine::Vec3 p = s.evaluate(u_at(i), v_at(j));
      float* at = &g.positions[(static_cast<std::size_t>(i) * g.nv + j) * 3];
      at[0] = static_cast<float>(p.x());
      at[1] = static_cast<float>(p.y());
      at[2] = static_cast<float>(p.z());
    }
  }
  for (int i = 0; i + 1 < g.nu; ++i) {
    for (int j = 0; j + 1 < g.nv; ++j) {
      if (region != nullptr && !region->contains(u_at(i + 0.5), v_at(j + 0.5))) continue;
      const auto k = static_cast<std::uint32_t>(i * g.nv + j);
      const auto n = static_cast<std::uint32_t>(g.nv);
      g.triangles.insert(g.triangles.end(), {k, k + n, k + n + 1, k, k + n + 1, k + 1});
    }
  }
}

}  // namespace

DisplayMesh tessellate(const engine::PreparedModel& prepared, std::size_t max_vertices) {
  const auto& surfaces = prepared.model().surfaces;
  std::vector<SurfaceGrid> grids(surfaces.size());
  // Samples per span; trimmed faces get a finer grid so their outline follows the trim.
  double per_span = 6.0;
  const auto plan = [&](double density) {
    std::size_t total = 0;
    for (std::size_t s = 0; s < surfaces.size(); ++s) {
      const engine::NurbsSurface& f = surfaces[s];
      const double fine = f.is_trimmed() ? 2.0 : 1.0;
      const int spans_u = distinct_spans(f.knots_u, f.degree_u, f.count_u);
      const int spans_v = distinct_spans(f.knots_v, f.degree_v, f.count_v);
      grids[s].nu = std::clamp(static_cast<int>(std::lround(spans_u * density * fine)) + 1, 3, 257);
      grids[s].nv = std::clamp(static_cast<int>(std::lround(spans_v * density * fine)) + 1, 3, 257);
      total += static_cast<std::size_t>(grids[s].nu) * grids[s].nv;
    }
    return total;
  };
  for (std::size_t total = plan(per_span); total > max_vertices && per_span > 0.25;
       total = plan(per_span)) {
    per_span *= std::sqrt(static_cast<double>(max_vertices) / static_cast<double>(total)) * 0.95;
  }
  tbb::parallel_for(std::size_t{0}, surfaces.size(), [&](std::size_t s) {
    sample(surfaces[s], prepared.surface_region(static_cast<int>(s)), grids[s]);
  });
  nurbsreg::engine::stop_if_cancelled();
  DisplayMesh mesh;
  for (const SurfaceGrid& g : grids) {
    const auto base = static_cast<std::uint32_t>(mesh.vertex_count());
    mesh.positions.insert(mesh.positions.end(), g.positions.begin(), g.positions.end());
    for (const std::uint32_t k : g.triangles)
      mesh.triangles.push_back(base + k);
  }
  return mesh;
}

}  // namespace nurbsreg::inspect
