#include "bench_models.hpp"

#include <cmath>
#include <numbers>
#include <random>

#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/engine/shapes.hpp"

namespace nurbsreg::bench {
namespace {

using engine::Vec3;

// Clamped uniform knot vector for `count` control points of degree `degree` on [0, 1].
std::vector<double> uniform_clamped_knots(int count, int degree) {
  const int spans = count - degree;
  std::vector<double> knots;
  knots.reserve(count + degree + 1);
  for (int k = 0; k <= degree; ++k)
    knots.push_back(0.0);
  for (int k = 1; k < spans; ++k)
    knots.push_back(static_cast<double>(k) / spans);
  for (int k = 0; k <= degree; ++k)
    knots.push_back(1.0);
  return knots;
}

double unit(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

}  // namespace

BenchModel make_panel(int n) {
  engine::NurbsSurface s;
  s.name = "panel";
  s.degree_u = 3;
  s.degree_v = 3;
  s.count_u = n;
  s.count_v = n;
  s.knots_u = uniform_clamped_knots(n, 3);
  s.knots_v = uniform_clamped_knots(n, 3);
  std::mt19937_64 rng(0x9a9e1 + n);
  const double pi = std::numbers::pi;
  // A doubly curved sheet with a few bumps; the finer model also carries shorter waves so its
  // 1,369 patches are not just a refinement of a simple shape.
  const double fine = n > 20 ? 1.0 : 0.0;
  s.control_points.resize(static_cast<std::size_t>(n) * n);
  const double step = 100.0 / (n - 1);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x = i * step + (i > 0 && i < n - 1 ? (unit(rng) - 0.5) * 0.3 * step : 0.0);
      const double y = j * step + (j > 0 && j < n - 1 ? (unit(rng) - 0.5) * 0.3 * step : 0.0);
      const double z = 12.0 * std::sin(pi * x / 70.0) * std::cos(pi * y / 90.0) +
                       6.0 * (x / 100.0) * (x / 100.0) - 4.0 * (y / 100.0) +
                       fine * 1.5 * std::sin(2.0 * pi * x / 19.0) * std::sin(2.0 * pi * y / 23.0) +
                       (unit(rng) - 0.5) * (fine > 0 ? 0.4 : 1.5);
      s.control_points[static_cast<std::size_t>(i) * n + j] = Vec3(x, y, z);
    }
  }
  const int patches = (n - 3) * (n - 3);
  BenchModel m;
  m.name = "panel" + std::to_string(patches);
  m.description = "bicubic panel, " + std::to_string(n) + " x " + std::to_string(n) +
                  " control points, " + std::to_string(patches) + " patches";
  m.model.surfaces.push_back(std::move(s));
  return m;
}

BenchModel make_sphere_model() {
  BenchModel m;
  m.name = "sphere";
  m.description = "exact rational sphere r = 50 mm, degree (2, 2), 8 patches, poles and seam";
  m.model.surfaces.push_back(engine::make_sphere(Vec3::Zero(), 50.0));
  m.model.surfaces.back().name = "sphere";
  return m;
}

BenchModel make_folded() {
  engine::NurbsSurface s;
  s.name = "folded";
  s.degree_u = 3;
  s.degree_v = 3;
  const double gap = 2.0;
  // Cross-section (x, z) around the fold: the lower layer runs from x = 100 to the fold at
  // x ~ -3, the upper layer comes back 2 mm above it.
  const double xs[] = {100, 70, 40, 15, 0, -4, -4, 0, 15, 40, 70, 100};
  const double zs[] = {0, 0, 0, 0, 0, 0, gap, gap, gap, gap, gap, gap};
  s.count_u = 12;
  s.count_v = 8;
  s.knots_u = uniform_clamped_knots(s.count_u, 3);
  s.knots_v = uniform_clamped_knots(s.count_v, 3);
  s.control_points.resize(static_cast<std::size_t>(s.count_u) * s.count_v);
  const double pi = std::numbers::pi;
  for (int i = 0; i < s.count_u; ++i) {
    for (int j = 0; j < s.count_v; ++j) {
      const double y = 60.0 * j / (s.count_v - 1);
      // The same waviness on both layers keeps the gap close to 2 mm everywhere.
      const double wave = 3.0 * std::sin(pi * xs[i] / 60.0) * std::cos(pi * y / 45.0);
      s.control_points[static_cast<std::size_t>(i) * s.count_v + j] = Vec3(xs[i], y, zs[i] + wave);
    }
  }
  BenchModel m;
  m.name = "folded";
  m.description = "bicubic sheet folded over itself, 2 mm gap, 12 x 8 control points, 45 patches";
  m.model.surfaces.push_back(std::move(s));
  return m;
}

std::vector<BenchModel> all_models() {
  std::vector<BenchModel> models;
  models.push_back(make_panel(10));
  models.push_back(make_panel(40));
  models.push_back(make_sphere_model());
  models.push_back(make_folded());
  return models;
}

Box sample_bounds(const engine::Model& model) {
  Box box{Vec3::Constant(INFINITY), Vec3::Constant(-INFINITY)};
  for (const auto& s : model.surfaces) {
    const auto du = s.domain_u();
    const auto dv = s.domain_v();
    const int n = 200;
    for (int a = 0; a <= n; ++a) {
      for (int b = 0; b <= n; ++b) {
        const Vec3 p = s.evaluate(du.to_parent(double(a) / n), dv.to_parent(double(b) / n));
        box.lo = box.lo.cwiseMin(p);
        box.hi = box.hi.cwiseMax(p);
      }
    }
  }
  return box;
}

PointSet make_points(const engine::Model& model, const Box& box, std::size_t count,
                     double perturbation, std::uint64_t seed) {
  PointSet set;
  set.base.resize(count);
  set.measured.resize(count);
  const std::size_t near_count = (count + 1) / 2;
  const auto samples = engine::sample_surfaces(model, near_count, seed);
  std::mt19937_64 rng(seed ^ 0x5eedf00dULL);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double diagonal = box.diagonal();
  const Vec3 extent = box.hi - box.lo;
  const Vec3 lo = box.lo - 0.25 * extent;
  const Vec3 size = 1.5 * extent;
  for (std::size_t i = 0; i < count; ++i) {
    Vec3 p;
    if (i % 2 == 0) {
      const auto& s = samples[i / 2];
      p = s.point + s.normal * ((unit(rng) * 2.0 - 1.0) * 0.02 * diagonal);
    } else {
      p = lo + Vec3(unit(rng) * size.x(), unit(rng) * size.y(), unit(rng) * size.z());
    }
    Vec3 direction(gauss(rng), gauss(rng), gauss(rng));
    direction.normalize();
    set.base[i] = p;
    set.measured[i] = p + perturbation * direction;
  }
  return set;
}

}  // namespace nurbsreg::bench
