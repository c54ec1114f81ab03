#pragma once
// Brute-force point-to-surface distance for io tests (an oracle independent of the engine's
// projectors): the nearest sample of a dense parameter grid, refined by damped Gauss-Newton
// (Levenberg-Marquardt) in (u, v) clamped to the domain. Exact enough (~1e-12 relative) for
// points that lie on the surface, which is what the io tests check.

#include <Eigen/Cholesky>
#include <algorithm>
#include <limits>
#include <vector>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::test {

using engine::NurbsSurface;
using engine::Vec3;

// A grid of samples (8 per control point in each direction) of one surface, built once.
struct SampledSurface {
  const NurbsSurface* surface;
  std::vector<Vec3> points;
  std::vector<Eigen::Vector2d> params;
};

inline SampledSurface sample(const NurbsSurface& s) {
  SampledSurface out{&s, {}, {}};
  const auto du = s.domain_u();
  const auto dv = s.domain_v();
  const int nu = 8 * s.count_u;
  const int nv = 8 * s.count_v;
  for (int i = 0; i <= nu; ++i) {
    for (int j = 0; j <= nv; ++j) {
      const double u = du.to_parent(static_cast<double>(i) / nu);
      const double v = dv.to_parent(static_cast<double>(j) / nv);
      out.points.push_back(s.evaluate(u, v));
      out.params.emplace_back(u, v);
    }
  }
  return out;
}

// Distance from p to the surface: the best grid sample, refined by damped Gauss-Newton in
// (u, v) clamped to the domain.
inline double distance_to(const SampledSurface& sampled, const Vec3& p) {
  const NurbsSurface& s = *sampled.surface;
  const auto du = s.domain_u();
  const auto dv = s.domain_v();
  double best = std::numeric_limits<double>::infinity();
  double u = du.lo, v = dv.lo;
  for (std::size_t k = 0; k < sampled.points.size(); ++k) {
    const double d = (sampled.points[k] - p).squaredNorm();
    if (d < best) best = d, u = sampled.params[k][0], v = sampled.params[k][1];
  }
  double lambda = 1e-9;
  for (int it = 0; it < 100; ++it) {
    const auto d = s.derivatives(u, v);
    const Vec3 r = d.s - p;
    Eigen::Matrix2d jtj;
    jtj << d.su.dot(d.su), d.su.dot(d.sv), d.su.dot(d.sv), d.sv.dot(d.sv);
    const Eigen::Vector2d g(d.su.dot(r), d.sv.dot(r));
    jtj.diagonal() *= 1.0 + lambda;
    jtj.diagonal().array() += 1e-300;
    const Eigen::Vector2d step = jtj.ldlt().solve(-g);
    const double un = std::clamp(u + step[0], du.lo, du.hi);
    const double vn = std::clamp(v + step[1], dv.lo, dv.hi);
    if ((s.evaluate(un, vn) - p).squaredNorm() < r.squaredNorm()) {
      u = un, v = vn, lambda *= 0.1;
    } else {
      lambda *= 10;
      if (lambda > 1e12) break;
    }
  }
  return (s.evaluate(u, v) - p).norm();
}

}  // namespace nurbsreg::test
