#include "reference.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace nurbsreg::bench {
namespace {

using engine::Vec3;

// Distinct breakpoints of a knot vector inside the domain [knots[p], knots[count]].
std::vector<double> breakpoints(const std::vector<double>& knots, int degree, int count) {
  std::vector<double> out;
  for (int k = degree; k <= count; ++k) {
    if (out.empty() || knots[k] > out.back()) out.push_back(knots[k]);
  }
  return out;
}

// Cell edges: every knot span split evenly so that the surface gets at least `target` cells.
std::vector<double> cell_edges(const std::vector<double>& bp, int target) {
  const int spans = static_cast<int>(bp.size()) - 1;
  const int split = std::max(2, (target + spans - 1) / spans);
  std::vector<double> edges;
  for (int s = 0; s < spans; ++s) {
    for (int k = 0; k < split; ++k)
      edges.push_back(bp[s] + (bp[s + 1] - bp[s]) * k / split);
  }
  edges.push_back(bp.back());
  return edges;
}

double box_squared_distance(const Vec3& lo, const Vec3& hi, const Vec3& p) {
  const Vec3 d = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
  return d.squaredNorm();
}

constexpr int kCellsPerDirection = 96;
constexpr int kSamplesPerCell = 4;  // 5 x 5 sample grid per cell
constexpr int kBlockCells = 8;      // blocks of 8 x 8 cells

}  // namespace

Reference::Reference(const engine::Model& model) : model_(model) {
  double diagonal = 0.0;
  for (int si = 0; si < static_cast<int>(model.surfaces.size()); ++si) {
    const auto& s = model.surfaces[si];
    const auto eu = cell_edges(breakpoints(s.knots_u, s.degree_u, s.count_u), kCellsPerDirection);
    const auto ev = cell_edges(breakpoints(s.knots_v, s.degree_v, s.count_v), kCellsPerDirection);
    const int nu = static_cast<int>(eu.size()) - 1;
    const int nv = static_cast<int>(ev.size()) - 1;
    const std::size_t first_cell = cells_.size();
    for (int a = 0; a < nu; ++a) {
      for (int b = 0; b < nv; ++b) {
        Cell c;
        c.lo = Vec3::Constant(INFINITY);
        c.hi = Vec3::Constant(-INFINITY);
        c.u0 = eu[a];
        c.u1 = eu[a + 1];
        c.v0 = ev[b];
        c.v1 = ev[b + 1];
        c.surface = si;
        const auto mid = s.derivatives(0.5 * (c.u0 + c.u1), 0.5 * (c.v0 + c.v1));
        c.center = mid.s;
        c.normal = mid.su.cross(mid.sv);
        const double length = c.normal.norm();
        c.normal = length > 1e-12 * (mid.su.norm() * mid.sv.norm()) && length > 0
                       ? Vec3(c.normal / length)
                       : Vec3::Zero();
        c.slab_lo = INFINITY;
        c.slab_hi = -INFINITY;
        double max_uu = 0.0;
        double max_vv = 0.0;
        for (int i = 0; i <= kSamplesPerCell; ++i) {
          for (int j = 0; j <= kSamplesPerCell; ++j) {
            const double u = c.u0 + (c.u1 - c.u0) * i / kSamplesPerCell;
            const double v = c.v0 + (c.v1 - c.v0) * j / kSamplesPerCell;
            const auto d = s.derivatives(u, v);
            c.lo = c.lo.cwiseMin(d.s);
            c.hi = c.hi.cwiseMax(d.s);
            const double offset = c.normal.dot(d.s - c.center);
            c.slab_lo = std::min(c.slab_lo, offset);
            c.slab_hi = std::max(c.slab_hi, offset);
            max_uu = std::max(max_uu, d.suu.norm());
            max_vv = std::max(max_vv, d.svv.norm());
          }
        }
        // Bilinear interpolation on a sub-square of size h_u x h_v deviates from S by at most
        // (h_u^2 max|S_uu| + h_v^2 max|S_vv|) / 8, and the interpolant stays inside the box
        // and the slab of the samples (both convex); 1.5x covers the maxima between samples.
        const double hu = (c.u1 - c.u0) / kSamplesPerCell;
        const double hv = (c.v1 - c.v0) / kSamplesPerCell;
        const double margin = 1.5 * (hu * hu * max_uu + hv * hv * max_vv) / 8.0;
        c.lo.array() -= margin;
        c.hi.array() += margin;
        c.slab_lo -= margin;
        c.slab_hi += margin;
        cells_.push_back(c);
      }
    }
    for (int a0 = 0; a0 < nu; a0 += kBlockCells) {
      for (int b0 = 0; b0 < nv; b0 += kBlockCells) {
        Block block{Vec3::Constant(INFINITY), Vec3::Constant(-INFINITY), {}};
        for (int a = a0; a < std::min(nu, a0 + kBlockCells); ++a) {
          for (int b = b0; b < std::min(nv, b0 + kBlockCells); ++b) {
            const auto index = static_cast<std::uint32_t>(first_cell + a * nv + b);
            block.cells.push_back(index);
            block.lo = block.lo.cwiseMin(cells_[index].lo);
            block.hi = block.hi.cwiseMax(cells_[index].hi);
          }
        }
        blocks_.push_back(std::move(block));
      }
    }
    for (std::size_t k = first_cell; k < cells_.size(); ++k) {
      diagonal = std::max(diagonal, (cells_[k].hi - cells_[k].lo).norm());
    }
  }
  // Absolute safety added to every cell (rounding in the samples).
  const double pad = 1e-12 * std::max(diagonal, 1.0);
  for (auto& c : cells_) {
    c.lo.array() -= pad;
    c.hi.array() += pad;
    c.slab_lo -= pad;
    c.slab_hi += pad;
  }
}

double Reference::cell_bound(const Cell& cell, const Vec3& p) const {
  const double box = box_squared_distance(cell.lo, cell.hi, p);
  const double offset = cell.normal.dot(p - cell.center);
  const double slab = std::max({0.0, offset - cell.slab_hi, cell.slab_lo - offset});
  return std::max(box, slab * slab);
}

double Reference::polish(const Cell& cell, const Vec3& p, double& u, double& v) const {
  const auto& s = model_.surfaces[cell.surface];
  u = 0.5 * (cell.u0 + cell.u1);
  v = 0.5 * (cell.v0 + cell.v1);
  auto d = s.derivatives(u, v);
  Vec3 r = d.s - p;
  double f = r.squaredNorm();
  const double wu = cell.u1 - cell.u0;
  const double wv = cell.v1 - cell.v0;
  for (int iteration = 0; iteration < 60; ++iteration) {
    // Gradient and Hessian of f/2 = |S - p|^2 / 2.
    const double gu = r.dot(d.su);
    const double gv = r.dot(d.sv);
    double huu = d.su.dot(d.su) + r.dot(d.suu);
    double huv = d.su.dot(d.sv) + r.dot(d.suv);
    double hvv = d.sv.dot(d.sv) + r.dot(d.svv);
    // Active set of the box constraints (projected Newton, Bertsekas 1982): a variable at a
    // bound whose gradient pushes outward is held fixed.
    const bool fix_u = (u <= cell.u0 && gu > 0) || (u >= cell.u1 && gu < 0);
    const bool fix_v = (v <= cell.v0 && gv > 0) || (v >= cell.v1 && gv < 0);
    double step_u = 0.0;
    double step_v = 0.0;
    auto solve = [&](double a, double b, double c) {
      // [a b; b c] [su sv]' = -[gu gv]' on the free variables.
      if (!fix_u && !fix_v) {
        const double det = a * c - b * b;
        if (a > 0 && det > 1e-14 * a * c) {
          step_u = -(c * gu - b * gv) / det;
          step_v = -(a * gv - b * gu) / det;
          return true;
        }
        return false;
      }
      if (!fix_u && a > 0) step_u = -gu / a;
      if (!fix_v && c > 0) step_v = -gv / c;
      return (fix_u || a > 0) && (fix_v || c > 0);
    };
    if (!solve(huu, huv, hvv)) {
      // Not convex here: Gauss-Newton (J^T J is positive semi-definite, still a descent
      // direction), then steepest descent scaled to the cell if even that is singular (pole).
      huu = d.su.dot(d.su);
      huv = d.su.dot(d.sv);
      hvv = d.sv.dot(d.sv);
      if (!solve(huu, huv, hvv)) {
        const double norm = std::hypot(gu * wu, gv * wv);
        if (norm == 0.0) break;
        step_u = fix_u ? 0.0 : -gu * wu * wu / norm * 0.25;
        step_v = fix_v ? 0.0 : -gv * wv * wv / norm * 0.25;
      }
    }
    // Converged: the step is below rounding of the parameters (at a constrained optimum the
    // projected step is zero).
    const double relative = std::max(std::abs(step_u) / wu, std::abs(step_v) / wv);
    if (!(relative > 1e-15)) break;
    double t = 1.0;
    bool improved = false;
    double nu = u;
    double nv = v;
    for (; t * relative > 1e-16; t *= 0.5) {
      nu = std::clamp(u + t * step_u, cell.u0, cell.u1);
      nv = std::clamp(v + t * step_v, cell.v0, cell.v1);
      const Vec3 q = s.evaluate(nu, nv);
      if ((q - p).squaredNorm() < f) {
        improved = true;
        break;
      }
    }
    if (!improved) break;
    const bool tiny = std::abs(nu - u) <= 1e-15 * wu && std::abs(nv - v) <= 1e-15 * wv;
    u = nu;
    v = nv;
    d = s.derivatives(u, v);
    r = d.s - p;
    f = r.squaredNorm();
    if (tiny) break;
  }
  return f;
}

ReferenceFoot Reference::search(const Vec3& p, Scratch& scratch) const {
  double best_sq = std::numeric_limits<double>::infinity();
  ReferenceFoot foot;
  auto& blocks = scratch.blocks;
  blocks.clear();
  for (std::uint32_t b = 0; b < blocks_.size(); ++b) {
    blocks.push_back({box_squared_distance(blocks_[b].lo, blocks_[b].hi, p), b});
  }
  std::sort(blocks.begin(), blocks.end(),
            [](const Candidate& x, const Candidate& y) { return x.bound < y.bound; });
  for (const Candidate& block : blocks) {
    if (block.bound >= best_sq) break;
    auto& cells = scratch.cells;
    cells.clear();
    for (const std::uint32_t c : blocks_[block.index].cells) {
      const double bound = cell_bound(cells_[c], p);
      if (bound < best_sq) cells.push_back({bound, c});
    }
    std::sort(cells.begin(), cells.end(),
              [](const Candidate& x, const Candidate& y) { return x.bound < y.bound; });
    for (const Candidate& cell : cells) {
      if (cell.bound >= best_sq) break;
      double u = 0.0;
      double v = 0.0;
      const double f = polish(cells_[cell.index], p, u, v);
      if (f < best_sq) {
        best_sq = f;
        foot.surface = cells_[cell.index].surface;
        foot.u = u;
        foot.v = v;
      }
    }
  }
  foot.distance = std::sqrt(best_sq);
  if (foot.surface >= 0) {
    const auto& s = model_.surfaces[foot.surface];
    const auto du = s.domain_u();
    const auto dv = s.domain_v();
    const double eu = 1e-12 * du.width();
    const double ev = 1e-12 * dv.width();
    foot.on_boundary = foot.u <= du.lo + eu || foot.u >= du.hi - eu || foot.v <= dv.lo + ev ||
                       foot.v >= dv.hi - ev;
  }
  return foot;
}

ReferenceFoot Reference::compute_one(const Vec3& p) const {
  Scratch scratch;
  return search(p, scratch);
}

std::vector<ReferenceFoot> Reference::compute(std::span<const Vec3> points) const {
  std::vector<ReferenceFoot> feet(points.size());
  tbb::enumerable_thread_specific<Scratch> scratch;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 64),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      Scratch& local = scratch.local();
                      for (std::size_t i = range.begin(); i < range.end(); ++i) {
                        feet[i] = search(points[i], local);
                      }
                    });
  return feet;
}

}  // namespace nurbsreg::bench
