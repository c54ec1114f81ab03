#pragma once
// Independent check of a convexity claim, for tests only: the Hessian of F = |S - p|^2 from the
// Bézier patch's own derivatives (not from the Bernstein bounds that made the claim).

#include <cmath>

#include "nurbsreg/engine/bezier.hpp"

namespace nurbsreg::test {

// The smallest eigenvalue sign test of the 2x2 Hessian of F/2 = (Su.Su + r.Suu, ...) at (s, t),
// with a rounding allowance relative to its size.
inline bool hessian_positive_definite(const engine::BezierPatch& patch, const engine::Vec3& p,
                                      double s, double t) {
  engine::Vec3 d[6];
  patch.derivatives(s, t, d);
  const engine::Vec3 r = d[0] - p;
  const double hss = d[1].dot(d[1]) + r.dot(d[3]);
  const double hst = d[1].dot(d[2]) + r.dot(d[4]);
  const double htt = d[2].dot(d[2]) + r.dot(d[5]);
  const double scale = std::abs(hss) + std::abs(htt) + std::abs(hst);
  const double tolerance = 1e-10 * scale;
  return hss > -tolerance && htt > -tolerance && hss * htt - hst * hst > -tolerance * scale;
}

}  // namespace nurbsreg::test
