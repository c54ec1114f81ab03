#pragma once
// Brute-force closest point on a NURBS curve, independent of the engine's projection code:
// dense sampling of every knot span with NurbsCurve::evaluate, then Newton polish (with
// NurbsCurve::derivatives) from every sampled local minimum of the distance, end points
// included. Slow and simple on purpose: it is the oracle the projectors are checked against.

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "nurbsreg/engine/nurbs_curve.hpp"

namespace nurbsreg::test {

struct ReferenceHit {
  double u = 0.0;
  double distance = std::numeric_limits<double>::infinity();
  engine::Vec3 foot = engine::Vec3::Zero();
};

// Parameters: `samples_per_span` equally spaced samples in every non-empty knot span of the
// domain, plus the domain end.
inline std::vector<double> reference_samples(const engine::NurbsCurve& curve,
                                             int samples_per_span) {
  const engine::ParamInterval dom = curve.domain();
  std::vector<double> breaks;
  for (double k : curve.knots) {
    if (k >= dom.lo && k <= dom.hi && (breaks.empty() || k > breaks.back())) breaks.push_back(k);
  }
  std::vector<double> us;
  for (std::size_t i = 0; i + 1 < breaks.size(); ++i) {
    for (int s = 0; s < samples_per_span; ++s) {
      us.push_back(breaks[i] + (breaks[i + 1] - breaks[i]) * s / samples_per_span);
    }
  }
  us.push_back(dom.hi);
  return us;
}

inline ReferenceHit reference_closest(const engine::NurbsCurve& curve, const engine::Vec3& p,
                                      const std::vector<double>& us) {
  using engine::Vec3;
  const engine::ParamInterval dom = curve.domain();
  std::vector<double> d2(us.size());
  ReferenceHit best;
  double best_d2 = std::numeric_limits<double>::infinity();
  const auto consider = [&](double u) {
    const Vec3 c = curve.evaluate(u);
    const double e = (c - p).squaredNorm();
    if (e < best_d2) {
      best_d2 = e;
      best.u = u;
      best.foot = c;
    }
    return e;
  };
  for (std::size_t j = 0; j < us.size(); ++j)
    d2[j] = consider(us[j]);
  const std::size_t last = us.size() - 1;
  for (std::size_t j = 0; j <= last; ++j) {
    const bool local_min = (j == 0 || d2[j] <= d2[j - 1]) && (j == last || d2[j] <= d2[j + 1]);
    if (!local_min) continue;
    // Newton on g(u) = (C(u) - p).C'(u), clamped to the domain; every iterate is a candidate,
    // so the polish can only improve on the sample.
    double u = us[j];
    for (int it = 0; it < 60; ++it) {
      Vec3 d[3];
      curve.derivatives(u, 2, d);
      const Vec3 r = d[0] - p;
      const double g = r.dot(d[1]);
      const double gp = d[1].squaredNorm() + r.dot(d[2]);
      if (!(gp > 0.0)) break;
      const double next = std::clamp(u - g / gp, dom.lo, dom.hi);
      if (next == u) break;
      u = next;
      consider(u);
    }
  }
  best.distance = std::sqrt(best_d2);
  return best;
}

inline ReferenceHit reference_closest(const engine::NurbsCurve& curve, const engine::Vec3& p,
                                      int samples_per_span = 64) {
  return reference_closest(curve, p, reference_samples(curve, samples_per_span));
}

}  // namespace nurbsreg::test
