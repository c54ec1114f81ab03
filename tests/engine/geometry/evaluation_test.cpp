// Evaluation and derivatives of the geometry core:
//  1. exact shapes (make_circle / make_sphere / make_torus): points on the analytic shape to
//     1e-14 relative, first and second derivatives equal to closed-form analytic ones;
//  2. finite differences against NurbsCurve / NurbsSurface / BezierCurve / BezierPatch
//     ::derivatives on random rational and non-rational, clamped and unclamped entities of
//     degree 1 to 12, inside spans, exactly at knots (one-sided limits on both sides, C0
//     joints included) and at the domain ends.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "nurbsreg/engine/bezier.hpp"
#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::random_curve;
using test::random_surface;
using test::uniform;

constexpr double kPi = std::numbers::pi;
constexpr double kEps = std::numeric_limits<double>::epsilon();

// ---------------------------------------------------------------------------------------------
// 1. Exact shapes against closed forms.
//
// Every span of make_circle (and each half of make_sphere's meridian) is a rational quadratic
// Bézier arc with control points A, A + B, B (A, B orthonormal, around the centre) and weights
// (1, 1/sqrt(2), 1). Independently of the engine: the classical quarter-circle parametrisation
// (1 - s^2, 2s) / (1 + s^2) = (cos theta, sin theta) with theta = 2 atan(s), s in [0, 1], is the
// rational Bézier with the same points and weights (1, 1, 2); the reparametrisation
// s = mu t / ((1 - t) + mu t) multiplies weight i by mu^i (The NURBS Book §6.1), so mu = 1/sqrt(2)
// gives weights (1, mu, 2 mu^2) = (1, 1/sqrt(2), 1). Hence on one span, with local t,
//   theta(t) = 2 atan(s(t)),  s = mu t / (1 - a t),  a = 1 - mu,
//   s' = mu / (1 - a t)^2,  s'' = 2 a mu / (1 - a t)^3,
//   theta' = 2 s' / (1 + s^2),  theta'' = 2 s'' / (1 + s^2) - 4 s s'^2 / (1 + s^2)^2,
// and the point is A cos theta + B sin theta. Below, `Angle` carries theta and its first two
// derivatives with respect to the parent parameter (chain rule with dt/du = spans per unit).

struct Angle {
  double value, d1, d2;
};

// Angle along a closed circle made of `quarters` equal quarter-arc spans over [0, 1]
// (4 for make_circle; 2 for the sphere's meridian, starting at its north pole).
Angle arc_angle(double u, int quarters) {
  const int q = std::min(quarters - 1, static_cast<int>(std::floor(u * quarters)));
  const double t = u * quarters - q;
  const double mu = 1.0 / std::sqrt(2.0);
  const double a = 1.0 - mu;
  const double den = 1.0 - a * t;
  const double s = mu * t / den;
  const double s1 = mu / (den * den);
  const double s2 = 2.0 * a * mu / (den * den * den);
  const double g = 1.0 + s * s;
  const double n = quarters;
  return {q * kPi / 2 + 2.0 * std::atan(s), n * 2.0 * s1 / g,
          n * n * (2.0 * s2 / g - 4.0 * s * s1 * s1 / (g * g))};
}

// Deterministic parameters: a uniform grid that includes every knot (multiples of 1/8) plus
// random ones.
std::vector<double> shape_parameters(int grid, int random, std::uint64_t seed) {
  std::vector<double> us;
  for (int k = 0; k <= grid; ++k)
    us.push_back(static_cast<double>(k) / grid);
  std::mt19937_64 rng(seed);
  for (int k = 0; k < random; ++k)
    us.push_back(uniform(rng, 0.0, 1.0));
  return us;
}

TEST(ExactShapes, CircleMatchesTheClosedForm) {
  const Vec3 c(3.0, -2.0, 1.5);
  const double r = 7.0;
  const NurbsCurve circle = make_circle(c, r);
  ASSERT_FALSE(circle.validate()) << *circle.validate();
  double worst_radius = 0.0;
  double worst_d1 = 0.0;
  double worst_d2 = 0.0;
  for (double u : shape_parameters(4000, 2000, 1)) {
    Vec3 d[3];
    circle.derivatives(u, 2, d);
    const Angle th = arc_angle(u, 4);
    const Vec3 radial(std::cos(th.value), std::sin(th.value), 0.0);
    const Vec3 tangent(-std::sin(th.value), std::cos(th.value), 0.0);
    worst_radius = std::max(worst_radius, std::abs((d[0] - c).norm() - r) / r);
    worst_radius = std::max(worst_radius, (d[0] - (c + r * radial)).norm() / r);
    // Scale: |C'| <= r * 4 * sqrt(2), |C''| <= r * 16 * 2 on these spans.
    worst_d1 = std::max(worst_d1, (d[1] - r * th.d1 * tangent).norm() / (r * th.d1));
    const Vec3 second = r * th.d2 * tangent - r * th.d1 * th.d1 * radial;
    worst_d2 = std::max(worst_d2, (d[2] - second).norm() / (r * th.d1 * th.d1));
  }
  EXPECT_LT(worst_radius, 1e-14);
  // Derivatives: a handful of rounding steps on values of size |C'|, |C''| (the quotient rule
  // A4.2 divides by w >= 1/sqrt(2) only); 1e-13 relative leaves room for ~500 ulp.
  EXPECT_LT(worst_d1, 1e-13);
  EXPECT_LT(worst_d2, 1e-13);
}

TEST(ExactShapes, SphereMatchesTheClosedForm) {
  const Vec3 c(-1.0, 4.0, 2.0);
  const double r = 25.0;
  const NurbsSurface sphere = make_sphere(c, r);
  ASSERT_FALSE(sphere.validate()) << *sphere.validate();
  const std::vector<double> us = shape_parameters(64, 16, 2);
  const std::vector<double> vs = shape_parameters(64, 16, 3);
  double worst_point = 0.0;
  double worst_first = 0.0;
  double worst_second = 0.0;
  for (double u : us) {
    // phi: polar angle from the north pole; the meridian is a half circle in two quarter spans.
    const Angle phi = arc_angle(u, 2);
    const double sp = std::sin(phi.value);
    const double cp = std::cos(phi.value);
    for (double v : vs) {
      const Angle lam = arc_angle(v, 4);
      const double sl = std::sin(lam.value);
      const double cl = std::cos(lam.value);
      const Vec3 n(sp * cl, sp * sl, cp);       // unit radial
      const Vec3 e_phi(cp * cl, cp * sl, -sp);  // d n / d phi
      const Vec3 e_lam(-sl, cl, 0.0);           // horizontal unit tangent
      const Vec3 rho(cl, sl, 0.0);
      const SurfaceDerivatives d = sphere.derivatives(u, v);
      worst_point = std::max(worst_point, std::abs((d.s - c).norm() - r) / r);
      worst_point = std::max(worst_point, (d.s - (c + r * n)).norm() / r);
      const Vec3 su = r * phi.d1 * e_phi;
      const Vec3 sv = r * sp * lam.d1 * e_lam;
      const Vec3 suu = r * phi.d2 * e_phi - r * phi.d1 * phi.d1 * n;
      const Vec3 suv = r * phi.d1 * cp * lam.d1 * e_lam;
      const Vec3 svv = r * sp * (lam.d2 * e_lam - lam.d1 * lam.d1 * rho);
      // Relative to the derivative scales of the sphere (r * phi', r * lam', squares): S_v
      // vanishes at the poles, so a relative-to-itself measure would be meaningless there.
      const double s1 = r * std::max(phi.d1, lam.d1);
      worst_first = std::max({worst_first, (d.su - su).norm() / s1, (d.sv - sv).norm() / s1});
      const double s2 =
          s1 * std::max(phi.d1, lam.d1) + r * std::max(std::abs(phi.d2), std::abs(lam.d2));
      worst_second = std::max({worst_second, (d.suu - suu).norm() / s2, (d.suv - suv).norm() / s2,
                               (d.svv - svv).norm() / s2});
    }
  }
  EXPECT_LT(worst_point, 1e-14);
  EXPECT_LT(worst_first, 1e-13);
  EXPECT_LT(worst_second, 1e-13);
}

TEST(ExactShapes, TorusMatchesTheClosedForm) {
  const Vec3 c(10.0, 0.0, -5.0);
  const double big_r = 40.0;
  const double small_r = 10.0;
  const NurbsSurface torus = make_torus(c, big_r, small_r);
  ASSERT_FALSE(torus.validate()) << *torus.validate();
  const std::vector<double> us = shape_parameters(64, 16, 4);
  const std::vector<double> vs = shape_parameters(64, 16, 5);
  double worst_point = 0.0;
  double worst_first = 0.0;
  double worst_second = 0.0;
  for (double u : us) {
    const Angle al = arc_angle(u, 4);  // around the tube
    const double ca = std::cos(al.value);
    const double sa = std::sin(al.value);
    const double rho = big_r + small_r * ca;
    const double rho1 = -small_r * sa * al.d1;
    const double rho2 = -small_r * (ca * al.d1 * al.d1 + sa * al.d2);
    const double z = small_r * sa;
    const double z1 = small_r * ca * al.d1;
    const double z2 = small_r * (ca * al.d2 - sa * al.d1 * al.d1);
    for (double v : vs) {
      const Angle lam = arc_angle(v, 4);  // around the axis
      const Vec3 radial(std::cos(lam.value), std::sin(lam.value), 0.0);
      const Vec3 tangent(-std::sin(lam.value), std::cos(lam.value), 0.0);
      const Vec3 ez(0.0, 0.0, 1.0);
      const SurfaceDerivatives d = torus.derivatives(u, v);
      // Implicit form: (|(x, y)| - R)^2 + z^2 = r^2 about the centre.
      const Vec3 q = d.s - c;
      const double tube = Vec2(q.head<2>().norm() - big_r, q.z()).norm();
      worst_point = std::max(worst_point, std::abs(tube - small_r) / (big_r + small_r));
      worst_point = std::max(worst_point, (q - (rho * radial + z * ez)).norm() / (big_r + small_r));
      const Vec3 su = rho1 * radial + z1 * ez;
      const Vec3 sv = rho * lam.d1 * tangent;
      const Vec3 suu = rho2 * radial + z2 * ez;
      const Vec3 suv = rho1 * lam.d1 * tangent;
      const Vec3 svv = rho * (lam.d2 * tangent - lam.d1 * lam.d1 * radial);
      const double s1 = (big_r + small_r) * std::max(al.d1, lam.d1);
      worst_first = std::max({worst_first, (d.su - su).norm() / s1, (d.sv - sv).norm() / s1});
      const double s2 = s1 * std::max(al.d1, lam.d1) +
                        (big_r + small_r) * std::max(std::abs(al.d2), std::abs(lam.d2));
      worst_second = std::max({worst_second, (d.suu - suu).norm() / s2, (d.suv - suv).norm() / s2,
                               (d.svv - svv).norm() / s2});
    }
  }
  EXPECT_LT(worst_point, 1e-14);
  EXPECT_LT(worst_first, 1e-13);
  EXPECT_LT(worst_second, 1e-13);
}

// ---------------------------------------------------------------------------------------------
// 2. Finite differences.
//
// Stencils (fourth order, Fornberg 1988): central
//   D(h) = (f(x-2h) - 8 f(x-h) + 8 f(x+h) - f(x+2h)) / (12 h),
// one-sided (h < 0 gives the backward one)
//   D(h) = (-25 f(x) + 48 f(x+h) - 36 f(x+2h) + 16 f(x+3h) - 3 f(x+4h)) / (12 h).
// Both have error c h^4 + O(h^5) where f is smooth on the stencil, so Richardson's
//   R = (16 D(h) - D(2h)) / 15
// is the returned estimate and |D(h) - D(2h)| / 15 estimates D(h)'s own truncation error (an
// upper bound for R's, which is O(h^5)). Rounding: a computed f carries an absolute error
// delta ~ a few ulp of its terms' size N (the noise scale: max |P| for points, see
// derivative_noise for first derivatives), times the rational evaluation's conditioning
// (weights span e^{+-1.5} here). The stencils' sum |coefficients| / 12 is 1.5 (central) or
// 10.7 (one-sided); with Richardson's 16/15 and the 2h stencil, rounding in R is at most
// ~11.7 delta / h. The tolerance
//   tol = 10 * truncation estimate + 100 eps N / h
// allows delta ~ 8 eps N; the measured worst |engine - FD| / tol over all cases is 0.68. A
// mistake in a derivative formula is an O(1) relative error, many orders above tol (which is
// ~1e-10 of the derivative's size).
// Stencils never cross a knot: interior samples keep 8h away from knots, and at knots the
// one-sided stencil on the side being checked is used.

enum class Side { kCentral, kForward, kBackward };

struct Fd {
  Vec3 value;
  double tolerance;
};

Fd finite_difference(const std::function<Vec3(double)>& f, double x, double h, Side side,
                     double noise_scale) {
  double m = noise_scale;
  auto eval = [&](double y) {
    const Vec3 p = f(y);
    m = std::max(m, p.norm());
    return p;
  };
  auto stencil = [&](double step) -> Vec3 {
    if (side == Side::kCentral) {
      return (eval(x - 2 * step) - 8.0 * eval(x - step) + 8.0 * eval(x + step) -
              eval(x + 2 * step)) /
             (12.0 * step);
    }
    const double s = side == Side::kForward ? step : -step;
    return (-25.0 * eval(x) + 48.0 * eval(x + s) - 36.0 * eval(x + 2 * s) + 16.0 * eval(x + 3 * s) -
            3.0 * eval(x + 4 * s)) /
           (12.0 * s);
  };
  const Vec3 d1 = stencil(h);
  const Vec3 d2 = stencil(2 * h);
  const double truncation = (d1 - d2).norm() / 15.0;
  return {(16.0 * d1 - d2) / 15.0, 10.0 * truncation + 100.0 * kEps * m / h};
}

double max_norm(const std::vector<Vec3>& points) {
  double m = 0.0;
  for (const Vec3& p : points)
    m = std::max(m, p.norm());
  return m;
}

// Rounding in a computed first derivative is relative to its terms, not to its value (which
// may cancel to almost nothing): sum_i |N_i'| |P_i| <= 2 p / (span width) * max |P| for B-spline
// and Bernstein bases alike (derivative = p times a difference of degree p - 1 bases).
double derivative_noise(int degree, double p_max, double span_width) {
  return 2.0 * degree * p_max / span_width;
}

// Step: ~1e-5 of the parameter range, but at most 1/64 of the local span width so the 8-step
// one-sided stencils stay inside the span (random knots can be very close).
double step_for(double span_width) {
  return std::min(1e-5, span_width / 64.0);
}

// Records the worst ratio |engine - FD| / tol over all checks of a test.
struct Worst {
  double ratio = 0.0;
  int checks = 0;
  void add(const Vec3& engine, const Fd& fd) {
    const double r = (engine - fd.value).norm() / fd.tolerance;
    ratio = std::max(ratio, r);
    ++checks;
  }
};

// Distinct knot values inside [lo, hi] (with the ends).
std::vector<double> breakpoints(const std::vector<double>& knots, double lo, double hi) {
  std::vector<double> b;
  for (double k : knots) {
    if (k >= lo && k <= hi && (b.empty() || k != b.back())) b.push_back(k);
  }
  return b;
}

// Sample positions on a parameter axis with their stencil side and step: random interior
// points of every span (at least 8h from its ends), every knot from the right (forward),
// every knot and the domain end from the left (backward, evaluated one ulp below the knot so
// that the engine uses the left span too; the shift changes values by O(1e-16) only).
struct Sample {
  double x;
  Side side;
  double h;
  double width;  // of the span the stencil lies in
};

std::vector<Sample> axis_samples(const std::vector<double>& knots, double lo, double hi,
                                 std::mt19937_64& rng, int per_span) {
  const std::vector<double> b = breakpoints(knots, lo, hi);
  std::vector<Sample> out;
  for (std::size_t k = 0; k + 1 < b.size(); ++k) {
    const double h = step_for(b[k + 1] - b[k]);
    for (int s = 0; s < per_span; ++s) {
      out.push_back(
          {uniform(rng, b[k] + 8 * h, b[k + 1] - 8 * h), Side::kCentral, h, b[k + 1] - b[k]});
    }
    out.push_back({b[k], Side::kForward, h, b[k + 1] - b[k]});  // lo and every knot, right limit
    out.push_back({std::nextafter(b[k + 1], -1e300), Side::kBackward, h, b[k + 1] - b[k]});  // left
  }
  return out;
}

struct CurveCase {
  int degree;
  int count;
  bool rational;
  bool clamped;
};

void PrintTo(const CurveCase& c, std::ostream* os) {
  *os << "degree " << c.degree << ", " << c.count << " points, "
      << (c.rational ? "rational" : "non-rational") << ", "
      << (c.clamped ? "clamped" : "unclamped");
}

void check_curve_derivatives(const NurbsCurve& curve, std::uint64_t seed, Worst& first,
                             Worst& second) {
  const ParamInterval dom = curve.domain();
  const double p_max = max_norm(curve.control_points);
  std::mt19937_64 rng(seed);
  auto point = [&](double u) { return curve.evaluate(u); };
  auto tangent = [&](double u) {
    Vec3 d[2];
    curve.derivatives(u, 1, d);
    return d[1];
  };
  for (const Sample& s : axis_samples(curve.knots, dom.lo, dom.hi, rng, 6)) {
    Vec3 d[3];
    curve.derivatives(s.x, 2, d);
    EXPECT_LT((d[0] - curve.evaluate(s.x)).norm(), 1e-14 * (1.0 + d[0].norm()));
    first.add(d[1], finite_difference(point, s.x, s.h, s.side, p_max));
    // Second derivative against differences of the (separately checked) first derivative:
    // O(eps |C'| / h) rounding instead of O(eps |C| / h^2).
    second.add(d[2], finite_difference(tangent, s.x, s.h, s.side,
                                       derivative_noise(curve.degree, p_max, s.width)));
  }
}

class CurveDerivatives : public ::testing::TestWithParam<CurveCase> {};

TEST_P(CurveDerivatives, MatchFiniteDifferences) {
  const CurveCase c = GetParam();
  const NurbsCurve curve =
      random_curve(500 + 13 * c.degree + c.count, c.degree, c.count, c.rational, c.clamped);
  ASSERT_FALSE(curve.validate()) << *curve.validate();
  Worst first;
  Worst second;
  check_curve_derivatives(curve, 7 + c.degree, first, second);
  EXPECT_LT(first.ratio, 1.0) << "worst |C' - FD| / tol over " << first.checks << " checks";
  EXPECT_LT(second.ratio, 1.0) << "worst |C'' - FD| / tol over " << second.checks << " checks";
}

TEST_P(CurveDerivatives, BezierPiecesMatchFiniteDifferencesAndTheParent) {
  const CurveCase c = GetParam();
  const NurbsCurve curve =
      random_curve(500 + 13 * c.degree + c.count, c.degree, c.count, c.rational, c.clamped);
  Worst first;
  Worst second;
  double worst_chain = 0.0;
  // Knot insertion forms convex combinations of homogeneous points with positive weights, so
  // the pieces' points lie in the hull of the parent's: max_norm bounds them too.
  const double p_max = max_norm(curve.control_points);
  std::mt19937_64 rng(11);
  for (const BezierCurve& piece : decompose(curve)) {
    auto point = [&](double t) { return piece.evaluate(t); };
    auto tangent = [&](double t) {
      Vec3 d[2];
      piece.derivatives(t, 1, d);
      return d[1];
    };
    for (const Sample& s : axis_samples({0.0, 1.0}, 0.0, 1.0, rng, 4)) {
      const double t = s.side == Side::kBackward ? 1.0 : s.x;  // no span beyond t = 1
      Vec3 d[3];
      piece.derivatives(t, 2, d);
      first.add(d[1], finite_difference(point, t, s.h, s.side, p_max));
      second.add(
          d[2], finite_difference(tangent, t, s.h, s.side, derivative_noise(c.degree, p_max, 1.0)));
      // Chain rule to the parent: d/du = (1 / width) d/dt. At t = 1 the parent uses the next
      // span, so compare one ulp inside.
      const double u = std::min(piece.param.to_parent(t), std::nextafter(piece.param.hi, -1e300));
      Vec3 p[3];
      curve.derivatives(u, 2, p);
      const double w = piece.param.width();
      const double scale = 1.0 + d[0].norm() + d[1].norm() + d[2].norm();
      worst_chain =
          std::max({worst_chain, (d[0] - p[0]).norm() / scale, (d[1] - w * p[1]).norm() / scale,
                    (d[2] - w * w * p[2]).norm() / scale});
    }
  }
  EXPECT_LT(first.ratio, 1.0) << first.checks << " checks";
  EXPECT_LT(second.ratio, 1.0) << second.checks << " checks";
  // Decomposition (knot insertion) and Bernstein evaluation versus de Boor: a few hundred
  // rounding steps at most for degree 12.
  EXPECT_LT(worst_chain, 1e-11);
}

INSTANTIATE_TEST_SUITE_P(
    Random, CurveDerivatives,
    ::testing::Values(CurveCase{1, 7, false, true}, CurveCase{1, 7, true, false},
                      CurveCase{2, 9, true, true}, CurveCase{3, 12, false, true},
                      CurveCase{3, 12, true, false}, CurveCase{4, 10, false, false},
                      CurveCase{5, 14, true, true}, CurveCase{7, 16, true, false},
                      CurveCase{12, 20, false, true}, CurveCase{12, 26, true, true},
                      CurveCase{12, 20, true, false}));

// C0 joints: a knot of full multiplicity p with the control point before the joint moved, so the
// curve has a corner there. The right limit (engine at the knot) and the left limit (one ulp
// below) of C' must match the one-sided differences on each side, and they must differ.
TEST(CurveDerivatives, C0JointHasDifferentOneSidedLimits) {
  for (int degree : {1, 2, 3, 5, 12}) {
    NurbsCurve curve = random_curve(900 + degree, degree, degree + 6, true, true);
    const ParamInterval dom = curve.domain();
    const double joint = dom.to_parent(0.5);
    curve = insert_knot(curve, joint, degree);
    ASSERT_FALSE(curve.validate()) << *curve.validate();
    // The control point at the joint is the curve point; the one before it sets the left tangent.
    const auto it = std::lower_bound(curve.knots.begin(), curve.knots.end(), joint);
    const int joint_index = static_cast<int>(it - curve.knots.begin()) - 1;
    ASSERT_LT((curve.control_points[joint_index] - curve.evaluate(joint)).norm(), 1e-12);
    curve.control_points[joint_index - 1] += Vec3(0.3, -0.2, 0.25);
    const double h = 1e-5;
    auto point = [&](double u) { return curve.evaluate(u); };
    Vec3 right[3];
    Vec3 left[3];
    const double below = std::nextafter(joint, -1e300);
    curve.derivatives(joint, 2, right);
    curve.derivatives(below, 2, left);
    const double p_max = max_norm(curve.control_points);
    const Fd fd_right = finite_difference(point, joint, h, Side::kForward, p_max);
    const Fd fd_left = finite_difference(point, below, h, Side::kBackward, p_max);
    EXPECT_LT((right[1] - fd_right.value).norm(), fd_right.tolerance) << "degree " << degree;
    EXPECT_LT((left[1] - fd_left.value).norm(), fd_left.tolerance) << "degree " << degree;
    EXPECT_GT((right[1] - left[1]).norm(), 1e-3 * right[1].norm()) << "degree " << degree;
    // The point itself is continuous across the joint.
    EXPECT_LT((right[0] - left[0]).norm(), 1e-13 * (1.0 + right[0].norm()));
  }
}

struct SurfaceCase {
  int degree_u, degree_v, count_u, count_v;
  bool rational;
  bool clamped;
};

void PrintTo(const SurfaceCase& c, std::ostream* os) {
  *os << "degree (" << c.degree_u << ", " << c.degree_v << "), " << c.count_u << " x " << c.count_v
      << ", " << (c.rational ? "rational" : "non-rational") << ", "
      << (c.clamped ? "clamped" : "unclamped");
}

class SurfaceDerivativesTest : public ::testing::TestWithParam<SurfaceCase> {};

TEST_P(SurfaceDerivativesTest, MatchFiniteDifferences) {
  const SurfaceCase c = GetParam();
  const NurbsSurface s = random_surface(700 + 3 * c.degree_u + c.degree_v, c.degree_u, c.degree_v,
                                        c.count_u, c.count_v, c.rational, c.clamped);
  ASSERT_FALSE(s.validate()) << *s.validate();
  const ParamInterval du = s.domain_u();
  const ParamInterval dv = s.domain_v();
  std::mt19937_64 rng(19);
  const double p_max = max_norm(s.control_points);
  const std::vector<Sample> us = axis_samples(s.knots_u, du.lo, du.hi, rng, 1);
  const std::vector<Sample> vs = axis_samples(s.knots_v, dv.lo, dv.hi, rng, 1);
  Worst first;
  Worst second;
  for (const Sample& a : us) {
    for (const Sample& b : vs) {
      const SurfaceDerivatives d = s.derivatives(a.x, b.x);
      EXPECT_LT((d.s - s.evaluate(a.x, b.x)).norm(), 1e-14 * (1.0 + d.s.norm()));
      // Along u with v fixed, and along v with u fixed (the fixed parameter selects the same
      // span for every stencil point, so each stencil sees one polynomial/rational piece).
      auto su_of = [&](double u) { return s.derivatives(u, b.x).su; };
      auto sv_of_u = [&](double u) { return s.derivatives(u, b.x).sv; };
      auto sv_of_v = [&](double v) { return s.derivatives(a.x, v).sv; };
      first.add(d.su, finite_difference([&](double u) { return s.evaluate(u, b.x); }, a.x, a.h,
                                        a.side, p_max));
      first.add(d.sv, finite_difference([&](double v) { return s.evaluate(a.x, v); }, b.x, b.h,
                                        b.side, p_max));
      const double noise_su = derivative_noise(s.degree_u, p_max, a.width);
      const double noise_sv = derivative_noise(s.degree_v, p_max, b.width);
      second.add(d.suu, finite_difference(su_of, a.x, a.h, a.side, noise_su));
      second.add(d.suv, finite_difference(sv_of_u, a.x, a.h, a.side, noise_sv));
      second.add(d.svv, finite_difference(sv_of_v, b.x, b.h, b.side, noise_sv));
    }
  }
  EXPECT_LT(first.ratio, 1.0) << first.checks << " checks";
  EXPECT_LT(second.ratio, 1.0) << second.checks << " checks";
}

TEST_P(SurfaceDerivativesTest, BezierPatchesMatchFiniteDifferencesAndTheParent) {
  const SurfaceCase c = GetParam();
  const NurbsSurface s = random_surface(700 + 3 * c.degree_u + c.degree_v, c.degree_u, c.degree_v,
                                        c.count_u, c.count_v, c.rational, c.clamped);
  const std::vector<BezierPatch> patches = decompose(s);
  const double p_max = max_norm(s.control_points);  // bounds the patches' points (convex hull)
  const double noise_u = derivative_noise(c.degree_u, p_max, 1.0);
  const double noise_v = derivative_noise(c.degree_v, p_max, 1.0);
  Worst first;
  Worst second;
  double worst_chain = 0.0;
  std::mt19937_64 rng(23);
  // A few patches (all would be slow at degree 12): first, last and two random ones.
  std::vector<std::size_t> picks = {0, patches.size() - 1, rng() % patches.size(),
                                    rng() % patches.size()};
  for (std::size_t k : picks) {
    const BezierPatch& patch = patches[k];
    auto eval6 = [&](double a, double b) {
      std::array<Vec3, 6> out;
      patch.derivatives(a, b, out.data());
      return out;
    };
    const std::vector<Sample> axis = axis_samples({0.0, 1.0}, 0.0, 1.0, rng, 2);
    for (const Sample& a : axis) {
      for (const Sample& b : axis) {
        const double sa = a.side == Side::kBackward ? 1.0 : a.x;
        const double tb = b.side == Side::kBackward ? 1.0 : b.x;
        const std::array<Vec3, 6> d = eval6(sa, tb);
        EXPECT_LT((d[0] - patch.evaluate(sa, tb)).norm(), 1e-14 * (1.0 + d[0].norm()));
        first.add(d[1], finite_difference([&](double x) { return patch.evaluate(x, tb); }, sa, a.h,
                                          a.side, p_max));
        first.add(d[2], finite_difference([&](double y) { return patch.evaluate(sa, y); }, tb, b.h,
                                          b.side, p_max));
        second.add(d[3], finite_difference([&](double x) { return eval6(x, tb)[1]; }, sa, a.h,
                                           a.side, noise_u));
        second.add(d[4], finite_difference([&](double x) { return eval6(x, tb)[2]; }, sa, a.h,
                                           a.side, noise_v));
        second.add(d[5], finite_difference([&](double y) { return eval6(sa, y)[2]; }, tb, b.h,
                                           b.side, noise_v));
        // Chain rule to the parent (one ulp inside the box at the upper ends).
        const double u =
            std::min(patch.param_u.to_parent(sa), std::nextafter(patch.param_u.hi, -1e300));
        const double v =
            std::min(patch.param_v.to_parent(tb), std::nextafter(patch.param_v.hi, -1e300));
        const SurfaceDerivatives p = s.derivatives(u, v);
        const double wu = patch.param_u.width();
        const double wv = patch.param_v.width();
        double scale = 1.0;
        for (const Vec3& x : d)
          scale += x.norm();
        worst_chain = std::max(
            {worst_chain, (d[0] - p.s).norm() / scale, (d[1] - wu * p.su).norm() / scale,
             (d[2] - wv * p.sv).norm() / scale, (d[3] - wu * wu * p.suu).norm() / scale,
             (d[4] - wu * wv * p.suv).norm() / scale, (d[5] - wv * wv * p.svv).norm() / scale});
      }
    }
  }
  EXPECT_LT(first.ratio, 1.0) << first.checks << " checks";
  EXPECT_LT(second.ratio, 1.0) << second.checks << " checks";
  EXPECT_LT(worst_chain, 1e-11);
}

INSTANTIATE_TEST_SUITE_P(
    Random, SurfaceDerivativesTest,
    ::testing::Values(SurfaceCase{1, 1, 4, 5, false, true}, SurfaceCase{1, 1, 5, 4, true, false},
                      SurfaceCase{2, 3, 6, 7, true, true}, SurfaceCase{3, 3, 8, 8, false, true},
                      SurfaceCase{3, 3, 8, 9, true, false}, SurfaceCase{1, 4, 5, 8, true, true},
                      SurfaceCase{5, 2, 9, 6, false, false},
                      SurfaceCase{12, 12, 14, 14, true, true},
                      SurfaceCase{12, 3, 15, 6, false, false}));

}  // namespace
}  // namespace nurbsreg::engine
