#include "surface/patch_newton.hpp"

#include <algorithm>
#include <cmath>

#include "platform/cpu_dispatch.hpp"
#include "surface/patch_derivatives.hpp"

namespace nurbsreg::engine {

namespace {
// Inlined: it then runs in newton_core's own (possibly AVX2) code.
[[gnu::always_inline]] inline Vec3 unit_normal(const Vec3& su, const Vec3& sv) {
  const Vec3 n = su.cross(sv);
  const double scale = su.norm() * sv.norm();
  const double length = n.norm();
  if (scale > 0.0 && length > 1e-12 * scale) return n / length;
  return Vec3::Zero();
}
}  // namespace

NewtonPatch::NewtonPatch(const BezierPatch& bare)
    : patch(bare), unit_weights(unit_weights_of(bare)) {}

double newton_on_patch(const BezierPatch& patch, const Vec3& p, double s0, double s1, double t0,
                       double t1, double& s, double& t, Vec3& foot, SurfaceProjectionStats* stats,
                       Vec3* normal, bool* converged) {
  return newton_core(patch, p, s0, s1, t0, t1, s, t, foot, stats, normal,
                     std::numeric_limits<double>::infinity(), converged);
}

bool patch_tangents(const NewtonPatch& on, double s, double t, Vec3* out) {
  return patch_first_derivatives(on.patch, s, t, on.unit_weights, out);
}

double newton_to_proven_point(const NewtonPatch& on, const Vec3& p, double s0, double s1, double t0,
                              double t1, double& s, double& t, Vec3& foot, Vec3* normal,
                              bool* converged) {
  // 1e-10 of the patch's parameter range: the foot's error is then ~1e-10 of the patch's size
  // along the surface at most, and the squared distance's ~|H| 1e-20, far below the 1e-11 R the
  // clipping itself does not pursue.
  return newton_core(on, p, s0, s1, t0, t1, s, t, foot, nullptr, normal,
                     std::numeric_limits<double>::infinity(), converged, 1e-10);
}

NURBSREG_HOT_CLONES
double newton_core(const NewtonPatch& on, const Vec3& p, double s0, double s1, double t0, double t1,
                   double& s, double& t, Vec3& foot, SurfaceProjectionStats* stats, Vec3* normal,
                   double abort_at, bool* converged, double settled_step) {
  s = std::clamp(s, s0, s1);
  t = std::clamp(t, t0, t1);
  // Set when the iteration ends at a stationary (KKT) point of the box, not by the iteration cap,
  // a failed line search or a non-finite step.
  bool stationary = false;
  const BezierPatch& patch = on.patch;
  const bool unit = on.unit_weights;
  Vec3 d[6];
  patch_derivatives(patch, s, t, unit, d);
  Vec3 r = d[0] - p;
  double f = r.squaredNorm();
  long iterations = 0;
  for (int it = 0; it < 60; ++it) {
    ++iterations;
    const Vec3 &su = d[1], &sv = d[2];
    // Half gradient and half Hessian of F = |S - p|^2.
    const double gs = r.dot(su), gt = r.dot(sv);
    if (abort_at < std::numeric_limits<double>::infinity()) {
      // Tangent-plane lower bound of the convex F over the box (F_s = 2 gs, F_t = 2 gt).
      const double below = f + 2.0 * (std::min(gs * (s0 - s), gs * (s1 - s)) +
                                      std::min(gt * (t0 - t), gt * (t1 - t)));
      if (below >= abort_at) {
        if (stats) stats->newton_iterations += iterations;
        if (converged) *converged = false;
        return std::numeric_limits<double>::infinity();
      }
    }
    const double suu = su.dot(su), svv = sv.dot(sv);
    const double hss = suu + r.dot(d[3]);
    const double hst = su.dot(sv) + r.dot(d[4]);
    const double htt = svv + r.dot(d[5]);
    // Projected Newton: a variable at a bound whose gradient pushes outward is held fixed.
    // A gradient component below rounding (relative 1e-15) counts as zero: stationary. Compared
    // squared: |g| > 1e-15 |r| max(|S_s|, |S_t|) without the three roots.
    const double noise_sq = 1e-30 * f * std::max(suu, svv);
    const bool free_s =
        s1 > s0 && gs * gs > noise_sq && !((s <= s0 && gs > 0) || (s >= s1 && gs < 0));
    const bool free_t =
        t1 > t0 && gt * gt > noise_sq && !((t <= t0 && gt > 0) || (t >= t1 && gt < 0));
    if (!free_s && !free_t) {
      stationary = true;
      break;
    }
    double ds = 0, dt = 0;
    bool newton_step = false;
    if (free_s && free_t) {
      const double det = hss * htt - hst * hst;
      if (hss > 0 && htt > 0 && det > 1e-12 * hss * htt) {
        ds = -(htt * gs - hst * gt) / det;
        dt = -(hss * gt - hst * gs) / det;
        newton_step = true;
      } else {
        // Not locally convex: Gauss-Newton (J^T J is positive semi-definite), regularised for a
        // degenerate parametrisation (a pole, where S_t = 0).
        const double a = su.dot(su), b = su.dot(sv), c = sv.dot(sv);
        const double mu = 1e-10 * (a + c) + 1e-300;
        const double det2 = (a + mu) * (c + mu) - b * b;
        ds = -((c + mu) * gs - b * gt) / det2;
        dt = -((a + mu) * gt - b * gs) / det2;
      }
    } else if (free_s) {
      newton_step = hss > 0;
      ds = -gs / (newton_step ? hss : su.dot(su) + 1e-300);
    } else {
      newton_step = htt > 0;
      dt = -gt / (newton_step ? htt : sv.dot(sv) + 1e-300);
    }
    if (!free_s) ds = 0;
    if (!free_t) dt = 0;
    if (!std::isfinite(ds) || !std::isfinite(dt)) break;
    // Never try to leave the box by more than its size (gradient steps near a pole are huge).
    const double reach = std::max(std::abs(ds) / std::max(s1 - s0, 1e-300),
                                  std::abs(dt) / std::max(t1 - t0, 1e-300));
    if (reach > 1.0) {
      ds /= reach;
      dt /= reach;
    }
    // Converged: the step is below what a parameter in [0, 1] can resolve (the same threshold as
    // `moved` below, without spending an evaluation on it); or it is a full Newton step (positive
    // definite Hessian) below 1e-12 of the box, the size after which the loop below stops anyway
    // (the point is then ~1e-12 of the box from the minimiser: a foot within 1e-12 of the patch's
    // size, F within ~|H| 1e-24; the clipping accepts 1e-11 R), which saves the evaluation of
    // that last step (about one in four of a warm start's, 5% of a warm frame); or below
    // `settled_step` for a Newton step where the caller has proven F strictly convex (the point
    // is then that close to the minimiser and F within ~|H| settled_step^2 of the minimum).
    if (std::max(std::abs(ds), std::abs(dt)) <=
        (newton_step ? std::max(settled_step, 1e-12 * std::max(s1 - s0, t1 - t0)) : 1e-15)) {
      stationary = true;
      break;
    }
    // Rounding in |S - p|^2: S carries ~eps |S| absolute error, so F carries ~2 |r| eps |S|.
    // Only needed when the sufficient-decrease test fails (rarely): computed then (three roots).
    auto f_noise = [&] { return 1e-14 * r.norm() * (d[0].norm() + p.norm()) + 1e-300; };
    // On a box where the caller proved F strictly convex (settled_step above rounding), in the
    // quadratic regime (a full Newton step, both variables free, below 1e-6 of the box) the step
    // after this one is ~1e-12 of the box: the trial point gets S, S_s and S_t only, and when the
    // next Newton step, estimated with this iteration's Hessian (off by ~1e-6 relative), is
    // below settled_step, Newton ends there without second derivatives.
    if (settled_step > 1e-15 && newton_step && free_s && free_t &&
        std::max(std::abs(ds), std::abs(dt)) <= 1e-6 * std::max(s1 - s0, t1 - t0)) {
      const double ns = s + ds, nt = t + dt;
      Vec3 first[3];
      if (ns > s0 && ns < s1 && nt > t0 && nt < t1 &&
          patch_first_derivatives(patch, ns, nt, unit, first)) {
        const Vec3 nr = first[0] - p;
        const double nf = nr.squaredNorm();
        const double ngs = nr.dot(first[1]), ngt = nr.dot(first[2]);
        const double det = hss * htt - hst * hst;
        const double es = (htt * ngs - hst * ngt) / det, et = (hss * ngt - hst * ngs) / det;
        if (nf <= f + f_noise() && std::max(std::abs(es), std::abs(et)) <= settled_step) {
          ++iterations;
          s = ns;
          t = nt;
          d[0] = first[0];
          d[1] = first[1];
          d[2] = first[2];
          f = nf;
          stationary = true;
          break;
        }
      }
    }
    double step = 1.0;
    bool accepted = false;
    double ns = s, nt = t;
    // Trial points get all derivatives at once: the first trial is nearly always accepted and
    // its derivatives are then those of the next iteration.
    Vec3 trial[6];
    for (int ls = 0; ls < 60; ++ls) {
      ns = std::clamp(s + step * ds, s0, s1);
      nt = std::clamp(t + step * dt, t0, t1);
      patch_derivatives(patch, ns, nt, unit, trial);
      const double nf = (trial[0] - p).squaredNorm();
      const double predicted = 2.0 * (gs * (ns - s) + gt * (nt - t));
      const double moved = std::max(std::abs(ns - s), std::abs(nt - t));
      if (nf <= f + 1e-4 * predicted ||
          // In the quadratic regime the change of F drowns in rounding; a short Newton step is
          // still taken (it improves orthogonality) unless it visibly increases F.
          (newton_step && step == 1.0 && moved < 1e-6 && nf <= f + f_noise())) {
        accepted = true;
        break;
      }
      step *= 0.5;
    }
    if (!accepted) break;
    const double moved = std::max(std::abs(ns - s), std::abs(nt - t));
    s = ns;
    t = nt;
    std::copy(trial, trial + 6, d);
    r = d[0] - p;
    f = r.squaredNorm();
    if (moved <= 1e-15) {
      stationary = true;
      break;
    }
    // A full Newton step (positive definite Hessian) of size delta leaves an error of order
    // delta^2 (quadratic convergence): below 1e-12 the next step would be under 1e-15 relative
    // to the box up to the conditioning. We stop there instead of paying for that step.
    if (newton_step && step == 1.0 && moved <= 1e-12 * std::max(s1 - s0, t1 - t0)) {
      stationary = true;
      break;
    }
  }
  if (stats) stats->newton_iterations += iterations;
  foot = d[0];
  if (normal) *normal = unit_normal(d[1], d[2]);
  if (converged) *converged = stationary;
  return f;
}

}  // namespace nurbsreg::engine
