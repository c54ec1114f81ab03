#include "nurbsreg/icp/analytic.hpp"
#include "nurbsreg/engine/cancellation.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>

namespace nurbsreg::icp {
namespace {

using engine::Vec3;

template <class... Fs>
struct Overloaded : Fs... {
  using Fs::operator()...;
};
// Clang 14 (the sanitizer builds) does not deduce aggregate template arguments without it.
template <class... Fs>
Overloaded(Fs...) -> Overloaded<Fs...>;

bool finite(const Vec3& v) {
  return v.allFinite();
}

std::string field_error(const char* shape, const char* field, const std::string& what) {
  return std::string(shape) + ": " + field + ": " + what;
}

std::string got(double x) {
  std::ostringstream out;
  out << "(got " << x << ")";
  return out.str();
}

std::optional<std::string> check_unit(const char* shape, const char* field, const Vec3& v) {
  if (!finite(v)) return field_error(shape, field, "must be finite");
  if (std::abs(v.norm() - 1.0) > 1e-9) {
    return field_error(shape, field, "must be a unit vector " + got(v.norm()));
  }
  return std::nullopt;
}

// Some unit vector orthogonal to the unit vector n (deterministic).
Vec3 any_orthogonal(const Vec3& n) {
  const Vec3 helper = std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  return n.cross(helper).normalized();
}

Correspondence make(const Vec3& p, const Vec3& foot, const Vec3& normal, bool on_boundary = false) {
  Correspondence c;
  c.foot = foot;
  c.normal = normal;
  c.distance = (p - foot).norm();
  c.valid = true;
  c.on_boundary = on_boundary;
  return c;
}

const char* name_of(const Primitive& primitive) {
  return std::visit(
      Overloaded{[](const Plane&) { return "plane"; }, [](const Rectangle&) { return "rectangle"; },
                 [](const Sphere&) { return "sphere"; },
                 [](const Cylinder&) { return "cylinder"; }},
      primitive);
}

// Uniform double in [0, 1) from 53 random bits: same numbers on every platform, unlike
// std::uniform_real_distribution.
double unit_random(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

}  // namespace

std::optional<std::string> validate(const Primitive& primitive) {
  return std::visit(
      Overloaded{
          [](const Plane& s) -> std::optional<std::string> {
            if (!finite(s.origin)) return field_error("plane", "origin", "must be finite");
            return check_unit("plane", "normal", s.normal);
          },
          [](const Rectangle& s) -> std::optional<std::string> {
            if (!finite(s.origin)) return field_error("rectangle", "origin", "must be finite");
            if (auto e = check_unit("rectangle", "axis_u", s.axis_u)) return e;
            if (auto e = check_unit("rectangle", "axis_v", s.axis_v)) return e;
            if (std::abs(s.axis_u.dot(s.axis_v)) > 1e-9) {
              return field_error("rectangle", "axis_v", "must be orthogonal to axis_u");
            }
            if (!(s.half_u > 0.0 && std::isfinite(s.half_u))) {
              return field_error("rectangle", "half_u", "must be finite and > 0 " + got(s.half_u));
            }
            if (!(s.half_v > 0.0 && std::isfinite(s.half_v))) {
              return field_error("rectangle", "half_v", "must be finite and > 0 " + got(s.half_v));
            }
            return std::nullopt;
          },
          [](const Sphere& s) -> std::optional<std::string> {
            if (!finite(s.center)) return field_error("sphere", "center", "must be finite");
            if (!(s.radius > 0.0 && std::isfinite(s.radius))) {
              return field_error("sphere", "radius", "must be finite and > 0 " + got(s.radius));
            }
            return std::nullopt;
          },
          [](const Cylinder& s) -> std::optional<std::string> {
            if (!finite(s.origin)) return field_error("cylinder", "origin", "must be finite");
            if (auto e = check_unit("cylinder", "axis", s.axis)) return e;
            if (!(s.radius > 0.0 && std::isfinite(s.radius))) {
              return field_error("cylinder", "radius", "must be finite and > 0 " + got(s.radius));
            }
            if (!(s.half_length > 0.0)) {
              return field_error("cylinder", "half_length", "must be > 0 " + got(s.half_length));
            }
            return std::nullopt;
          }},
      primitive);
}

Correspondence closest_point(const Primitive& primitive, const Vec3& p) {
  return std::visit(
      Overloaded{[&](const Plane& s) {
                   return make(p, p - s.normal.dot(p - s.origin) * s.normal, s.normal);
                 },
                 [&](const Rectangle& s) {
                   // Clamping the in-plane coordinates is exact: the rectangle is convex and
                   // the squared distance splits into in-plane and normal parts.
                   const Vec3 d = p - s.origin;
                   const double u = s.axis_u.dot(d);
                   const double v = s.axis_v.dot(d);
                   const double x = std::clamp(u, -s.half_u, s.half_u);
                   const double y = std::clamp(v, -s.half_v, s.half_v);
                   return make(p, s.origin + x * s.axis_u + y * s.axis_v, s.axis_u.cross(s.axis_v),
                               x != u || y != v);
                 },
                 [&](const Sphere& s) {
                   const Vec3 d = p - s.center;
                   const double r = d.norm();
                   const Vec3 n = r > 0.0 ? Vec3(d / r) : Vec3(Vec3::UnitZ());
                   return make(p, s.center + s.radius * n, n);
                 },
                 [&](const Cylinder& s) {
                   // Nearest axial position within the finite length, then the radial
                   // direction: for the open lateral surface this is exact, including the rim.
                   const Vec3 d = p - s.origin;
                   const double along = s.axis.dot(d);
                   const Vec3 radial = d - along * s.axis;
                   const double r = radial.norm();
                   const Vec3 n = r > 0.0 ? Vec3(radial / r) : any_orthogonal(s.axis);
                   const double z = std::clamp(along, -s.half_length, s.half_length);
                   return make(p, s.origin + z * s.axis + s.radius * n, n, z != along);
                 }},
      primitive);
}

double area(const Primitive& primitive) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  return std::visit(
      Overloaded{
          [](const Plane&) { return kInf; },
          [](const Rectangle& s) { return 4.0 * s.half_u * s.half_v; },
          [](const Sphere& s) { return 4.0 * std::numbers::pi * s.radius * s.radius; },
          [](const Cylinder& s) { return 4.0 * std::numbers::pi * s.radius * s.half_length; }},
      primitive);
}

std::vector<Vec3> sample_uniform(std::span<const Primitive> primitives, std::size_t count,
                                 std::uint64_t seed) {
  if (primitives.empty()) throw std::invalid_argument("sample_uniform: no primitives");
  std::vector<double> cumulative;
  double total = 0.0;
  for (std::size_t i = 0; i < primitives.size(); ++i) {
    if (auto e = validate(primitives[i])) {
      throw std::invalid_argument("primitive " + std::to_string(i) + ": " + *e);
    }
    const double a = area(primitives[i]);
    if (!std::isfinite(a)) {
      throw std::invalid_argument("primitive " + std::to_string(i) + " (" + name_of(primitives[i]) +
                                  "): unbounded, cannot be sampled");
    }
    total += a;
    cumulative.push_back(total);
  }
  std::mt19937_64 rng(seed);
  std::vector<Vec3> points;
  points.reserve(count);
  for (std::size_t k = 0; k < count; ++k) {
    const double pick = unit_random(rng) * total;
    const std::size_t i = std::min<std::size_t>(
        std::upper_bound(cumulative.begin(), cumulative.end(), pick) - cumulative.begin(),
        primitives.size() - 1);
    const double a = unit_random(rng);
    const double b = unit_random(rng);
    points.push_back(std::visit(
        Overloaded{[](const Plane&) -> Vec3 { return Vec3::Zero(); },  // rejected above
                   [&](const Rectangle& s) -> Vec3 {
                     return s.origin + (2.0 * a - 1.0) * s.half_u * s.axis_u +
                            (2.0 * b - 1.0) * s.half_v * s.axis_v;
                   },
                   [&](const Sphere& s) -> Vec3 {
                     // Archimedes: z uniform in [-1, 1] and a uniform angle give a uniform
                     // distribution on the sphere.
                     const double z = 2.0 * a - 1.0;
                     const double phi = 2.0 * std::numbers::pi * b;
                     const double rho = std::sqrt(std::max(0.0, 1.0 - z * z));
                     return s.center + s.radius * Vec3(rho * std::cos(phi), rho * std::sin(phi), z);
                   },
                   [&](const Cylinder& s) -> Vec3 {
                     const Vec3 e1 = any_orthogonal(s.axis);
                     const Vec3 e2 = s.axis.cross(e1);
                     const double phi = 2.0 * std::numbers::pi * b;
                     return s.origin + (2.0 * a - 1.0) * s.half_length * s.axis +
                            s.radius * (std::cos(phi) * e1 + std::sin(phi) * e2);
                   }},
        primitives[i]));
  }
  return points;
}

UnionFinder::UnionFinder(std::vector<Primitive> primitives) : primitives_(std::move(primitives)) {
  if (primitives_.empty()) throw std::invalid_argument("UnionFinder: no primitives");
  for (std::size_t i = 0; i < primitives_.size(); ++i) {
    if (auto e = validate(primitives_[i])) {
      throw std::invalid_argument("primitive " + std::to_string(i) + ": " + *e);
    }
  }
}

void UnionFinder::find(const CorrespondenceQuery& query, std::span<Correspondence> out) {
  const auto answer = [&](std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      const Vec3& p = query.points[k];
      Correspondence best;
      for (const Primitive& primitive : primitives_) {
        const Correspondence c = closest_point(primitive, p);
        if (c.distance < best.distance) best = c;
      }
      best.valid = std::isfinite(best.distance) && best.distance <= query.max_distance;
      out[k] = best;
    }
  };
  if (query.parallel) {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, query.points.size(), 1024),
        [&](const tbb::blocked_range<std::size_t>& r) { answer(r.begin(), r.end()); });
    nurbsreg::engine::stop_if_cancelled();
  } else {
    answer(0, query.points.size());
  }
}

}  // namespace nurbsreg::icp
