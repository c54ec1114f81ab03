#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/engine/cancellation.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include <spdlog/spdlog.h>

#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/trim_region.hpp"
#include "synth/random_streams.hpp"

namespace nurbsreg::engine {
namespace {

// Cells per Bézier patch along each direction: for surface_area's quadrature, and for the
// sampler's rejection (whose density is exact on any cell; smaller cells only reject less).
constexpr int kAreaCells = 16;
constexpr int kSampleCells = 8;

struct Cell {
  int surface;
  int patch;  // index into Cells::patches
  // The cell [s0, s0 + size] x [t0, t0 + size] of the patch's local (s, t).
  double s0, t0, size;
  // Upper bound (estimate, see density_bound) of the area element |S_s x S_t| over the cell.
  double density_bound;
  // The face's region when a trim loop may cross the cell (its points are then kept only when
  // inside); null when the whole cell belongs to the face.
  const TrimRegion* region;
};

struct Cells {
  std::vector<TrimRegion> regions;
  std::vector<BezierPatch> patches;
  std::vector<Cell> cells;
  // Per cell, 2 x 2 Gauss-Legendre, the region not counted; surface_area's cells only.
  std::vector<double> areas;
};

struct AreaElement {
  double value;     // |S_s x S_t|
  double gradient;  // |d/ds| + |d/dt| of it, bounded through |N_s| and |N_t| (N = S_s x S_t)
};

AreaElement area_element(const BezierPatch& patch, double s, double t) {
  Vec3 d[6];
  patch.derivatives(s, t, d);
  const Vec3 n = d[1].cross(d[2]);
  const Vec3 n_s = d[3].cross(d[2]) + d[1].cross(d[4]);
  const Vec3 n_t = d[4].cross(d[2]) + d[1].cross(d[5]);
  return {n.norm(), n_s.norm() + n_t.norm()};
}

// An upper bound of the area element over a cell of local width h, from a 3 x 3 grid of values
// and gradient norms: every point of the cell lies within h / 4 of a grid point in s and in t,
// so the element exceeds that point's value by at most (|d/ds| + |d/dt|) h / 4 (h sqrt(2) / 4
// is taken). The gradient is known at the grid points only, so it is taken 1.5 times its
// largest value there: the bound is an estimate for what happens between them, which on an
// eighth of a patch (or a quarter of that, add_bounded_cell) is smooth.
double density_bound(const AreaElement (&grid)[3][3], double h) {
  double value = 0.0;
  double gradient = 0.0;
  for (const auto& row : grid) {
    for (const AreaElement& e : row) {
      value = std::max(value, e.value);
      gradient = std::max(gradient, e.gradient);
    }
  }
  // The relative 1e-9 covers rounding where the element is constant (a plane).
  return (value + 1.5 * gradient * h * std::sqrt(2.0) / 4.0) * (1.0 + 1e-9);
}

// 2 x 2 Gauss-Legendre over the cell.
double gauss_area(const BezierPatch& patch, const Cell& cell) {
  const double g = 0.5 / std::sqrt(3.0);
  double area = 0.0;
  for (double x : {0.5 - g, 0.5 + g}) {
    for (double y : {0.5 - g, 0.5 + g})
      area += area_element(patch, cell.s0 + x * cell.size, cell.t0 + y * cell.size).value;
  }
  return 0.25 * area * cell.size * cell.size;
}

// Simpson's rule on the cell's 3 x 3 grid: the cell's area, as far as its rejection needs it.
double simpson_area(const AreaElement (&grid)[3][3], double size) {
  constexpr double kWeight[3] = {1.0, 4.0, 1.0};
  double sum = 0.0;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j)
      sum += kWeight[i] * kWeight[j] * grid[i][j].value;
  }
  return sum / 36.0 * size * size;
}

// Keeps `cell` with its density bound, or, where the bound is far above the cell's mean area
// element (a rational patch whose weights squeeze its area into a corner of the cell), its four
// quarters: draws there would mostly be rejected, and the bound's estimate is more reliable on
// smaller cells.
void add_bounded_cell(const BezierPatch& patch, Cell cell, const AreaElement (&grid)[3][3],
                      int depth, std::vector<Cell>& cells) {
  constexpr int kMaxDepth = 6;  // quarters down to 1/512 of the patch
  cell.density_bound = density_bound(grid, cell.size);
  if (depth == kMaxDepth ||
      cell.density_bound * cell.size * cell.size <= 4.0 * simpson_area(grid, cell.size)) {
    cells.push_back(cell);
    return;
  }
  const double half = 0.5 * cell.size;
  for (int a = 0; a < 2; ++a) {
    for (int b = 0; b < 2; ++b) {
      Cell quarter = cell;
      quarter.s0 = cell.s0 + a * half;
      quarter.t0 = cell.t0 + b * half;
      quarter.size = half;
      AreaElement local[3][3];
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          // The quarter's corners are points of the parent's grid (one of them its centre).
          local[i][j] = i % 2 == 0 && j % 2 == 0 ? grid[a + i / 2][b + j / 2]
                                                 : area_element(patch, quarter.s0 + 0.5 * half * i,
                                                                quarter.t0 + 0.5 * half * j);
        }
      }
      add_bounded_cell(patch, quarter, local, depth + 1, cells);
    }
  }
}

// The cells of one patch: with `bounds` (the sampler), kSampleCells^2 cells with their density
// bounds, else kAreaCells^2 cells with their areas. The 3 x 3 grids of neighbouring cells share
// their edge values, so the patch is evaluated on one (2 n + 1)^2 grid; nothing is evaluated
// when no cell belongs to the face.
void patch_cells(const BezierPatch& patch, int surface, int patch_index, const TrimRegion* region,
                 bool bounds, std::vector<Cell>& cells, std::vector<double>& areas) {
  const int n = bounds ? kSampleCells : kAreaCells;
  const double h = 1.0 / n;
  RegionClass in_face[kAreaCells][kAreaCells];
  bool any = false;
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      in_face[a][b] = region == nullptr ? RegionClass::inside
                                        : region->classify(patch.param_u.to_parent(a * h),
                                                           patch.param_u.to_parent((a + 1) * h),
                                                           patch.param_v.to_parent(b * h),
                                                           patch.param_v.to_parent((b + 1) * h));
      any = any || in_face[a][b] != RegionClass::outside;
    }
  }
  if (!any) return;
  const int g = 2 * n + 1;
  std::vector<AreaElement> grid(bounds ? g * g : 0);
  for (int i = 0; bounds && i < g; ++i) {
    for (int j = 0; j < g; ++j)
      grid[i * g + j] = area_element(patch, 0.5 * h * i, 0.5 * h * j);
  }
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      if (in_face[a][b] == RegionClass::outside) continue;
      const Cell cell{surface,
                      patch_index,
                      a * h,
                      b * h,
                      h,
                      0.0,
                      in_face[a][b] == RegionClass::boundary ? region : nullptr};
      if (!bounds) {
        cells.push_back(cell);
        areas.push_back(gauss_area(patch, cell));
        continue;
      }
      AreaElement local[3][3];
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j)
          local[i][j] = grid[(2 * a + i) * g + 2 * b + j];
      }
      add_bounded_cell(patch, cell, local, 0, cells);
    }
  }
}

// Cells of every Bézier patch with their areas. A trimmed face keeps only the cells its region
// may meet (TrimRegion::classify); `regions` holds the regions the cells point to (reserved up
// front: the pointers stay valid). Patches are worked on in parallel, cells kept in patch order.
Cells collect_cells(const Model& model, bool bounds) {
  Cells out;
  out.regions.reserve(model.surfaces.size());
  std::vector<int> patch_surface;
  std::vector<const TrimRegion*> patch_region;
  for (std::size_t si = 0; si < model.surfaces.size(); ++si) {
    const NurbsSurface& s = model.surfaces[si];
    const TrimRegion* region = nullptr;
    if (!s.trim_loops.empty()) region = &out.regions.emplace_back(s);
    for (BezierPatch& patch : decompose(s)) {
      out.patches.push_back(std::move(patch));
      patch_surface.push_back(static_cast<int>(si));
      patch_region.push_back(region);
    }
  }
  const std::size_t n = out.patches.size();
  std::vector<std::vector<Cell>> cells(n);
  std::vector<std::vector<double>> areas(n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const auto& range) {
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      patch_cells(out.patches[k], patch_surface[k], static_cast<int>(k), patch_region[k], bounds,
                  cells[k], areas[k]);
    }
  });
  nurbsreg::engine::stop_if_cancelled();
  for (std::size_t k = 0; k < n; ++k) {
    out.cells.insert(out.cells.end(), cells[k].begin(), cells[k].end());
    out.areas.insert(out.areas.end(), areas[k].begin(), areas[k].end());
  }
  return out;
}

// The share of a cell inside its face: 1 for a cell wholly inside, else the fraction of an
// 8 x 8 grid of its points that the region contains.
double inside_fraction(const Cell& c, const BezierPatch& patch) {
  if (c.region == nullptr) return 1.0;
  constexpr int kGrid = 8;
  int inside = 0;
  for (int a = 0; a < kGrid; ++a) {
    for (int b = 0; b < kGrid; ++b) {
      inside += c.region->contains(patch.param_u.to_parent(c.s0 + (a + 0.5) / kGrid * c.size),
                                   patch.param_v.to_parent(c.t0 + (b + 0.5) / kGrid * c.size));
    }
  }
  return static_cast<double>(inside) / (kGrid * kGrid);
}

// Walker's alias table (Vose's construction): picks index k with probability weight[k] / sum
// from one uniform number in O(1).
class AliasTable {
 public:
  explicit AliasTable(const std::vector<double>& weights)
      : threshold_(weights.size()), alias_(weights.size()) {
    const std::size_t n = weights.size();
    double total = 0.0;
    for (double w : weights)
      total += w;
    std::vector<double> scaled(n);
    std::vector<std::size_t> small, large;
    for (std::size_t k = 0; k < n; ++k) {
      scaled[k] = weights[k] * static_cast<double>(n) / total;
      (scaled[k] < 1.0 ? small : large).push_back(k);
    }
    while (!small.empty() && !large.empty()) {
      const std::size_t s = small.back(), l = large.back();
      small.pop_back();
      threshold_[s] = scaled[s];
      alias_[s] = l;
      scaled[l] -= 1.0 - scaled[s];
      if (scaled[l] < 1.0) {
        large.pop_back();
        small.push_back(l);
      }
    }
    // What is left is 1 up to rounding.
    for (std::size_t k : small)
      threshold_[k] = 1.0, alias_[k] = k;
    for (std::size_t k : large)
      threshold_[k] = 1.0, alias_[k] = k;
  }
  // x uniform in [0, 1).
  std::size_t pick(double x) const {
    const double scaled = x * static_cast<double>(threshold_.size());
    const auto k = std::min(static_cast<std::size_t>(scaled), threshold_.size() - 1);
    return scaled - static_cast<double>(k) < threshold_[k] ? k : alias_[k];
  }

 private:
  std::vector<double> threshold_;
  std::vector<std::size_t> alias_;
};

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
  std::vector<SurfaceSample> samples;
  if (count == 0) return samples;
  const Cells c = collect_cells(model, true);
  std::vector<double> envelope(c.cells.size());
  double total = 0.0;
  for (std::size_t k = 0; k < c.cells.size(); ++k)
    total += envelope[k] = c.cells[k].density_bound * c.cells[k].size * c.cells[k].size;
  if (!(total > 0.0)) {
    throw std::runtime_error("sample_surfaces: the model has no surface area to sample");
  }
  // Rejection keeps the samples exactly uniform over the faces: a cell is proposed by its
  // envelope mass (density bound x cell area in (s, t)), a point uniformly
  // in the cell's (s, t), and the draw is kept with probability |S_s x S_t| / bound, and in a
  // cell that a trim loop crosses only inside the region; otherwise the whole draw starts again.
  // The cap stops a model whose trimmed faces have (next to) no area.
  const AliasTable table(envelope);
  samples.resize(count);
  const std::size_t chunks = (count + kSampleChunk - 1) / kSampleChunk;
  std::atomic<std::size_t> exceeded{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1), [&](const auto& range) {
    for (std::size_t chunk = range.begin(); chunk != range.end(); ++chunk) {
      const std::size_t begin = chunk * kSampleChunk;
      const std::size_t end = std::min(count, begin + kSampleChunk);
      const std::size_t max_draws = 1000 * (end - begin) + 100000;
      std::mt19937_64 rng(chunk_seed(seed, chunk));
      auto unit = [&rng] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
      std::size_t draws = 0;
      for (std::size_t i = begin; i < end;) {
        if (++draws > max_draws) {
          throw std::runtime_error(
              "sample_surfaces: the model's trimmed faces have too little area to sample (" +
              std::to_string(i - begin) + " of " + std::to_string(end - begin) +
              " points of a block after " + std::to_string(max_draws) + " draws)");
        }
        const Cell& cell = c.cells[table.pick(unit())];
        const BezierPatch& patch = c.patches[cell.patch];
        const double s = cell.s0 + unit() * cell.size;
        const double t = cell.t0 + unit() * cell.size;
        const double u = patch.param_u.to_parent(s);
        const double v = patch.param_v.to_parent(t);
        const double accept = unit() * cell.density_bound;
        if (cell.region != nullptr && !cell.region->contains(u, v)) continue;
        Vec3 d[6];
        patch.derivatives(s, t, d);
        const Vec3 n = d[1].cross(d[2]);
        const double element = n.norm();
        if (!(accept < element)) continue;
        if (element > cell.density_bound) exceeded.fetch_add(1, std::memory_order_relaxed);
        SurfaceSample& out = samples[i++];
        out.surface = cell.surface;
        out.u = u;
        out.v = v;
        out.point = d[0];
        const NurbsSurface& surface = model.surfaces[cell.surface];
        // The face's outer side, as the projector reports it (a reversed face's is
        // -(S_u x S_v)); S_s x S_t points the same way as S_u x S_v.
        out.normal = element > 1e-12 * d[1].norm() * d[2].norm() ? Vec3(n / element)
                                                                 : surface_normal(surface, u, v);
        if (surface.reversed) out.normal = -out.normal;
      }
    }
  });
  nurbsreg::engine::stop_if_cancelled();
  if (exceeded.load() > 0) {
    spdlog::warn(
        "sampling: the area element exceeded its estimated bound in {} of {} samples; the "
        "density is not exactly uniform there",
        exceeded.load(), count);
  }
  return samples;
}

double surface_area(const Model& model) {
  const Cells c = collect_cells(model, false);
  double total = 0.0;
  for (std::size_t k = 0; k < c.cells.size(); ++k)
    total += c.areas[k] * inside_fraction(c.cells[k], c.patches[c.cells[k].patch]);
  return total;
}

}  // namespace nurbsreg::engine
