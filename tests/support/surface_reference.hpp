#pragma once
// Independent brute-force closest point on a NURBS surface, for tests only. It uses nothing of the
// projection code: dense sampling through NurbsSurface::evaluate, the discrete local minima of
// the sample grid (best few hundred) polished by a box-constrained Newton on
// NurbsSurface::derivatives, and the four boundary curves sampled densely and polished in 1-D.
// Sampling is done once per surface (SurfaceReference), so a query costs a scan of the samples
// plus a few hundred short Newton runs.

#include <algorithm>
#include <cmath>
#include <vector>

#include "nurbsreg/engine/nurbs_surface.hpp"

namespace nurbsreg::test {

struct ReferenceHit {
  double u = 0, v = 0;
  double distance_sq = std::numeric_limits<double>::infinity();
  engine::Vec3 foot = engine::Vec3::Zero();
};

class SurfaceReference {
 public:
  explicit SurfaceReference(const engine::NurbsSurface& s, int grid = 160, int edge = 2000,
                            int seeds = 200)
      : s_(s), n_(grid), edge_(edge), seeds_(seeds), du_(s.domain_u()), dv_(s.domain_v()) {
    samples_.resize(static_cast<std::size_t>(n_ + 1) * (n_ + 1));
    for (int i = 0; i <= n_; ++i) {
      for (int j = 0; j <= n_; ++j)
        samples_[i * (n_ + 1) + j] = s_.evaluate(u_at(i), v_at(j));
    }
    for (int e = 0; e < 4; ++e) {
      for (int k = 0; k <= edge_; ++k) {
        const double x = static_cast<double>(k) / edge_;
        edges_[e].push_back(e < 2 ? s_.evaluate(e == 0 ? du_.lo : du_.hi, dv_.to_parent(x))
                                  : s_.evaluate(du_.to_parent(x), e == 2 ? dv_.lo : dv_.hi));
      }
    }
  }

  ReferenceHit closest(const engine::Vec3& p) const {
    const int m = n_ + 1;
    std::vector<double> d2(samples_.size());
    for (std::size_t k = 0; k < samples_.size(); ++k)
      d2[k] = (samples_[k] - p).squaredNorm();
    // Discrete local minima (<= all 8 neighbours) are the seeds; the global sample minimum is one.
    std::vector<std::pair<double, int>> minima;
    for (int i = 0; i < m; ++i) {
      for (int j = 0; j < m; ++j) {
        const double c = d2[i * m + j];
        bool is_min = true;
        for (int a = -1; a <= 1 && is_min; ++a) {
          for (int b = -1; b <= 1; ++b) {
            const int ii = i + a, jj = j + b;
            if ((a || b) && ii >= 0 && jj >= 0 && ii < m && jj < m && d2[ii * m + jj] < c) {
              is_min = false;
              break;
            }
          }
        }
        if (is_min) minima.emplace_back(c, i * m + j);
      }
    }
    std::sort(minima.begin(), minima.end());
    if (static_cast<int>(minima.size()) > seeds_) minima.resize(seeds_);
    ReferenceHit best;
    for (const auto& [value, k] : minima) {
      ReferenceHit h = polish(p, u_at(k / m), v_at(k % m), true, true);
      if (h.distance_sq < best.distance_sq) best = h;
    }
    for (int e = 0; e < 4; ++e) {
      std::vector<std::pair<double, int>> edge_best;
      for (int k = 0; k <= edge_; ++k) {
        edge_best.emplace_back((edges_[e][k] - p).squaredNorm(), k);
      }
      std::partial_sort(edge_best.begin(), edge_best.begin() + 8, edge_best.end());
      for (int r = 0; r < 8; ++r) {
        const double x = static_cast<double>(edge_best[r].second) / edge_;
        const double u = e < 2 ? (e == 0 ? du_.lo : du_.hi) : du_.to_parent(x);
        const double v = e < 2 ? dv_.to_parent(x) : (e == 2 ? dv_.lo : dv_.hi);
        ReferenceHit h = polish(p, u, v, e >= 2, e < 2);
        if (h.distance_sq < best.distance_sq) best = h;
      }
    }
    return best;
  }

 private:
  double u_at(int i) const { return du_.to_parent(static_cast<double>(i) / n_); }
  double v_at(int j) const { return dv_.to_parent(static_cast<double>(j) / n_); }

  // Projected Newton on |S - p|^2 over the domain; free_u / free_v false fixes that coordinate.
  ReferenceHit polish(const engine::Vec3& p, double u, double v, bool free_u, bool free_v) const {
    auto value = [&](double a, double b) { return (s_.evaluate(a, b) - p).squaredNorm(); };
    double f = value(u, v);
    for (int it = 0; it < 50; ++it) {
      const engine::SurfaceDerivatives d = s_.derivatives(u, v);
      const engine::Vec3 r = d.s - p;
      double gu = free_u ? r.dot(d.su) : 0.0, gv = free_v ? r.dot(d.sv) : 0.0;
      if ((u <= du_.lo && gu > 0) || (u >= du_.hi && gu < 0)) gu = 0;
      if ((v <= dv_.lo && gv > 0) || (v >= dv_.hi && gv < 0)) gv = 0;
      if (gu == 0 && gv == 0) break;
      double huu = d.su.dot(d.su) + r.dot(d.suu), hvv = d.sv.dot(d.sv) + r.dot(d.svv);
      double huv = d.su.dot(d.sv) + r.dot(d.suv);
      double su = 0, sv = 0;
      if (gu != 0 && gv != 0 && huu > 0 && huu * hvv - huv * huv > 0) {
        const double det = huu * hvv - huv * huv;
        su = -(hvv * gu - huv * gv) / det;
        sv = -(huu * gv - huv * gu) / det;
      } else {
        if (gu != 0) su = -gu / (huu > 0 ? huu : d.su.squaredNorm() + 1e-300);
        if (gv != 0) sv = -gv / (hvv > 0 ? hvv : d.sv.squaredNorm() + 1e-300);
      }
      double step = 1;
      bool moved = false;
      for (int ls = 0; ls < 50; ++ls) {
        const double nu = std::clamp(u + step * su, du_.lo, du_.hi);
        const double nv = std::clamp(v + step * sv, dv_.lo, dv_.hi);
        const double nf = value(nu, nv);
        if (nf < f || (nf <= f && (nu != u || nv != v))) {
          moved = std::abs(nu - u) + std::abs(nv - v) > 1e-16;
          u = nu;
          v = nv;
          f = nf;
          break;
        }
        step *= 0.5;
      }
      if (!moved) break;
    }
    return {u, v, f, s_.evaluate(u, v)};
  }

  const engine::NurbsSurface& s_;
  int n_, edge_, seeds_;
  engine::ParamInterval du_, dv_;
  std::vector<engine::Vec3> samples_;
  std::vector<engine::Vec3> edges_[4];
};

}  // namespace nurbsreg::test
