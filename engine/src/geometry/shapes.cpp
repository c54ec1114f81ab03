#include "nurbsreg/engine/shapes.hpp"

#include <array>
#include <cmath>

namespace nurbsreg::engine {
namespace {

constexpr double kHalfSqrt2 = 0.70710678118654752440;

// Unit circle control polygon (9 points on the square's corners and mid-edges) and weights.
constexpr std::array<std::array<double, 2>, 9> kUnitCircle = {
    {{1, 0}, {1, 1}, {0, 1}, {-1, 1}, {-1, 0}, {-1, -1}, {0, -1}, {1, -1}, {1, 0}}};
constexpr std::array<double, 9> kCircleWeights = {1,          kHalfSqrt2, 1,          kHalfSqrt2, 1,
                                                  kHalfSqrt2, 1,          kHalfSqrt2, 1};
const std::vector<double> kCircleKnots = {0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1};

// Half circle from angle +90 deg to -90 deg (north to south) in the (radial, z) plane.
constexpr std::array<std::array<double, 2>, 5> kHalfCircle = {
    {{0, 1}, {1, 1}, {1, 0}, {1, -1}, {0, -1}}};
constexpr std::array<double, 5> kHalfCircleWeights = {1, kHalfSqrt2, 1, kHalfSqrt2, 1};
const std::vector<double> kHalfCircleKnots = {0, 0, 0, 0.5, 0.5, 1, 1, 1};

}  // namespace

NurbsCurve make_circle(const Vec3& center, double radius) {
  NurbsCurve c;
  c.name = "circle";
  c.degree = 2;
  c.dimension = center.z() == 0.0 ? 2 : 3;
  c.knots = kCircleKnots;
  for (int i = 0; i < 9; ++i) {
    c.control_points.push_back(center + radius * Vec3(kUnitCircle[i][0], kUnitCircle[i][1], 0.0));
    c.weights.push_back(kCircleWeights[i]);
  }
  return c;
}

NurbsSurface make_sphere(const Vec3& center, double radius) {
  NurbsSurface s;
  s.name = "sphere";
  s.degree_u = 2;
  s.degree_v = 2;
  s.knots_u = kHalfCircleKnots;
  s.knots_v = kCircleKnots;
  s.count_u = 5;
  s.count_v = 9;
  for (int i = 0; i < 5; ++i) {
    const double rho = radius * kHalfCircle[i][0];
    const double z = radius * kHalfCircle[i][1];
    for (int j = 0; j < 9; ++j) {
      s.control_points.push_back(center +
                                 Vec3(rho * kUnitCircle[j][0], rho * kUnitCircle[j][1], z));
      s.weights.push_back(kHalfCircleWeights[i] * kCircleWeights[j]);
    }
  }
  return s;
}

NurbsSurface make_torus(const Vec3& center, double major_radius, double minor_radius) {
  NurbsSurface s;
  s.name = "torus";
  s.degree_u = 2;
  s.degree_v = 2;
  s.knots_u = kCircleKnots;
  s.knots_v = kCircleKnots;
  s.count_u = 9;
  s.count_v = 9;
  for (int i = 0; i < 9; ++i) {
    // Tube cross-section in the (radial, z) plane.
    const double rho = major_radius + minor_radius * kUnitCircle[i][0];
    const double z = minor_radius * kUnitCircle[i][1];
    for (int j = 0; j < 9; ++j) {
      s.control_points.push_back(center +
                                 Vec3(rho * kUnitCircle[j][0], rho * kUnitCircle[j][1], z));
      s.weights.push_back(kCircleWeights[i] * kCircleWeights[j]);
    }
  }
  return s;
}

}  // namespace nurbsreg::engine
