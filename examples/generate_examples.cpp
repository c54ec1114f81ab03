// Writes the example models of examples/ (units mm) through io::write_model:
//
//   generate_examples <output_dir>
//
// Every number that goes into a model is rounded to a few decimals first (knots to 1e-4,
// coordinates to 1e-3 mm, weights to 2-3 significant digits) so that the shortest round-trip
// form the writer emits stays short and the files small. The exact shapes (sphere, torus,
// circle) keep their exact weights (products of 1/sqrt(2)): their exactness is the point.
// Deterministic: no random numbers, so rerunning reproduces the committed files byte for byte.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "nurbsreg/engine/model.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/io/model_json.hpp"

namespace {

using nurbsreg::engine::Model;
using nurbsreg::engine::NurbsCurve;
using nurbsreg::engine::NurbsSurface;
using nurbsreg::engine::Vec3;

constexpr double kPi = std::numbers::pi;

// x rounded to `decimals` places. Dividing by an exact power of ten (rather than multiplying by
// 1e-3) gives the double nearest to the decimal, whose shortest round-trip form is that decimal.
double round_to(double x, int decimals) {
  const double scale = std::pow(10.0, decimals);  // an exact integer for decimals >= 0
  return std::round(x * scale) / scale;
}

// x > 0 rounded to `digits` significant digits (e.g. 10^0.5 -> 3.2, 10^-2 -> 0.01).
double round_significant(double x, int digits) {
  const int decimals = digits - 1 - static_cast<int>(std::floor(std::log10(x)));
  if (decimals >= 0) return round_to(x, decimals);
  const double scale = std::pow(10.0, -decimals);  // an exact integer
  return std::round(x / scale) * scale;
}

// Clamped knot vector on [0, 1] for `count` control points of degree `degree` whose interior
// knots are deliberately non-uniform: span widths vary smoothly by a factor of 2.5 to 5 (wide at
// one end, narrow in the middle-right), so the Bézier patches differ in size and the
// parametrisation is not arc-length-like. Interior knots rounded to 1e-4.
std::vector<double> nonuniform_knots(int degree, int count) {
  const int spans = count - degree;
  std::vector<double> widths(spans);
  double total = 0.0;
  for (int k = 0; k < spans; ++k) {
    const double s = (k + 0.5) / spans;
    widths[k] = 0.45 + std::cos(2.5 * kPi * s) * std::cos(2.5 * kPi * s) - 0.2 * s;
    total += widths[k];
  }
  std::vector<double> knots(degree + 1, 0.0);
  double u = 0.0;
  for (int k = 0; k + 1 < spans; ++k) {
    u += widths[k] / total;
    knots.push_back(round_to(u, 4));
  }
  knots.insert(knots.end(), degree + 1, 1.0);
  return knots;
}

// Greville abscissae (The NURBS Book eq. 9.8): placing control points there makes x(u) nearly
// linear, so the net follows the knot spacing and the panel has no folds.
std::vector<double> greville(const std::vector<double>& knots, int degree, int count) {
  std::vector<double> g(count);
  for (int i = 0; i < count; ++i) {
    double s = 0.0;
    for (int k = 1; k <= degree; ++k)
      s += knots[i + k];
    g[i] = s / degree;
  }
  return g;
}

// A smooth freeform height field on [0, 100]^2 mm with z between about 1 and 15 mm: a tilted
// dome, a saddle-like ripple and a bump, so curvature changes sign across the panel.
double panel_height(double x, double y) {
  const double sx = x / 100.0;
  const double sy = y / 100.0;
  return 6.0 + 4.0 * std::sin(kPi * sx) * std::sin(kPi * sy) + 2.5 * (sx - 0.5) * (sy - 0.3) * 4.0 +
         1.5 * std::cos(3.0 * kPi * sx + 1.0) * std::sin(2.0 * kPi * sy) +
         5.5 * std::exp(-((sx - 0.7) * (sx - 0.7) + (sy - 0.35) * (sy - 0.35)) / 0.02);
}

NurbsSurface make_panel(const std::string& name, int count) {
  NurbsSurface s;
  s.name = name;
  s.degree_u = 3;
  s.degree_v = 3;
  s.count_u = count;
  s.count_v = count;
  s.knots_u = nonuniform_knots(3, count);
  s.knots_v = nonuniform_knots(3, count);
  // v gets the knot widths mirrored, so the two directions differ.
  for (double& k : s.knots_v)
    k = round_to(1.0 - k, 4);
  std::reverse(s.knots_v.begin(), s.knots_v.end());
  const std::vector<double> gu = greville(s.knots_u, 3, count);
  const std::vector<double> gv = greville(s.knots_v, 3, count);
  for (int i = 0; i < count; ++i) {
    for (int j = 0; j < count; ++j) {
      // A gentle shear of the grid so that u- and v-lines are not axis-parallel.
      const double x = 100.0 * gu[i] + 3.0 * std::sin(kPi * gv[j]);
      const double y = 100.0 * gv[j] + 2.0 * std::sin(2.0 * kPi * gu[i]);
      s.control_points.emplace_back(round_to(x, 3), round_to(y, 3),
                                    round_to(panel_height(x, y), 3));
    }
  }
  return s;
}

// A bicubic sheet folded back over itself like a hairpin: the upper layer runs from x = 0 to
// x = 60 mm at z = +0.5, turns around a fold of radius ~0.5 mm and returns to x = 0 at z = -0.5.
// Both layers carry the same waviness in y, so the gap stays ~1 mm everywhere; a point between
// or near the layers has two near-equal local minima of the distance (one per layer), and near
// the fold a continuum of almost-equal ones.
NurbsSurface make_folded() {
  // Profile (x, z) in the u direction: the fold is a tight cubic turn over three control points.
  const std::vector<std::array<double, 2>> profile = {
      {0, 0.5},   {10, 0.5},  {20, 0.5},  {30, 0.5},  {40, 0.5},  {50, 0.5},
      {58, 0.5},  {61, 0.5},  {61, -0.5}, {58, -0.5}, {50, -0.5}, {40, -0.5},
      {30, -0.5}, {20, -0.5}, {10, -0.5}, {0, -0.5}};
  NurbsSurface s;
  s.name = "folded";
  s.degree_u = 3;
  s.degree_v = 3;
  s.count_u = static_cast<int>(profile.size());
  s.count_v = 8;
  // Uniform in u so that the surface is mirror-symmetric about the fold (u <-> 1 - u maps one
  // layer onto the other shifted by 1 mm in z).
  s.knots_u.assign(4, 0.0);
  for (int k = 1; k < s.count_u - 3; ++k)
    s.knots_u.push_back(round_to(k / (s.count_u - 3.0), 4));
  s.knots_u.insert(s.knots_u.end(), 4, 1.0);
  s.knots_v = {0, 0, 0, 0, 0.2, 0.4, 0.6, 0.8, 1, 1, 1, 1};
  for (int i = 0; i < s.count_u; ++i) {
    for (int j = 0; j < s.count_v; ++j) {
      const double y = 40.0 * j / (s.count_v - 1);
      // Same waviness for both layers (depends on x and y only): the layers stay parallel.
      const double x = profile[i][0];
      const double wave = 3.0 * std::sin(kPi * y / 40.0) + 1.5 * std::sin(kPi * x / 30.0);
      s.control_points.emplace_back(round_to(x, 3), round_to(y, 3),
                                    round_to(profile[i][1] + wave, 3));
    }
  }
  return s;
}

// A bicubic patch (6 x 6 control points, two interior knots each way) whose weights span
// 1e-2 .. 1e2: heavy weights pull the surface hard towards their control points, light ones let
// it ignore theirs, so the parametrisation is extremely uneven and the homogeneous coordinates
// span four orders of magnitude.
NurbsSurface make_rational_panel() {
  NurbsSurface s;
  s.name = "rational_panel";
  s.degree_u = 3;
  s.degree_v = 3;
  s.count_u = 6;
  s.count_v = 6;
  s.knots_u = {0, 0, 0, 0, 0.3, 0.55, 1, 1, 1, 1};
  s.knots_v = {0, 0, 0, 0, 0.45, 0.7, 1, 1, 1, 1};
  // log10 of the weights: exactly -2 and +2 occur (corner and interior), the rest in between.
  const double log_w[6][6] = {{-2.0, -1.0, 0.0, 0.5, 0.0, 1.0}, {-1.0, 0.0, 1.0, 2.0, 0.5, 0.0},
                              {0.0, 1.5, -1.5, 1.0, -0.5, 0.5}, {1.0, 0.5, 0.0, -1.0, 1.5, -1.0},
                              {0.5, -0.5, 2.0, 0.0, -2.0, 0.0}, {0.0, 1.0, -1.0, 0.5, 0.0, -0.5}};
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) {
      const double x = 12.0 * i;
      const double y = 12.0 * j;
      const double z = 5.0 * std::sin(0.09 * x) * std::cos(0.07 * y) + 0.1 * x;
      s.control_points.emplace_back(x, y, round_to(z, 3));
      s.weights.push_back(round_significant(std::pow(10.0, log_w[i][j]), 2));
    }
  }
  return s;
}

// A planar cubic (2-D coordinates in the file) with an inflection and a near-cusp tight turn.
NurbsCurve make_planar_curve() {
  NurbsCurve c;
  c.name = "planar_profile";
  c.degree = 3;
  c.dimension = 2;
  c.knots = {0, 0, 0, 0, 0.15, 0.3, 0.42, 0.5, 0.62, 0.8, 1, 1, 1, 1};
  c.control_points = {{0, 0, 0},   {15, 20, 0}, {35, 25, 0}, {50, 5, 0},  {52, -8, 0},
                      {45, -6, 0}, {47, 2, 0},  {65, 10, 0}, {80, -5, 0}, {95, 0, 0}};
  return c;
}

// A twisted space curve: a quintic on a conical helix with varying pitch (torsion != 0).
NurbsCurve make_twisted_curve() {
  NurbsCurve c;
  c.name = "twisted";
  c.degree = 5;
  c.dimension = 3;
  const int count = 14;
  c.knots = nonuniform_knots(5, count);
  for (int i = 0; i < count; ++i) {
    const double t = static_cast<double>(i) / (count - 1);
    const double angle = 3.0 * kPi * t;
    const double radius = 20.0 - 12.0 * t;
    c.control_points.emplace_back(round_to(radius * std::cos(angle), 3),
                                  round_to(radius * std::sin(angle), 3),
                                  round_to(30.0 * t * t + 5.0 * t, 3));
  }
  return c;
}

void write(const std::filesystem::path& dir, const std::string& file, const Model& model) {
  if (auto error = model.validate()) {
    throw std::runtime_error(file + ": generated model is invalid: " + *error);
  }
  const std::string path = (dir / file).string();
  nurbsreg::io::write_model(path, model);
  std::printf("%-22s %zu surfaces, %zu curves, %ju bytes\n", file.c_str(), model.surfaces.size(),
              model.curves.size(), static_cast<std::uintmax_t>(std::filesystem::file_size(path)));
}

Model single(NurbsSurface s) {
  Model m;
  m.surfaces.push_back(std::move(s));
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: generate_examples <output_dir>\n");
    return 2;
  }
  try {
    const std::filesystem::path dir = argv[1];
    std::filesystem::create_directories(dir);
    write(dir, "panel.json", single(make_panel("panel", 10)));
    write(dir, "panel_1369.json", single(make_panel("panel_1369", 40)));
    write(dir, "sphere.json", single(nurbsreg::engine::make_sphere(Vec3(0, 0, 0), 25.0)));
    write(dir, "torus.json", single(nurbsreg::engine::make_torus(Vec3(0, 0, 0), 40.0, 10.0)));
    write(dir, "folded.json", single(make_folded()));
    write(dir, "rational_panel.json", single(make_rational_panel()));
    Model curves;
    curves.curves.push_back(make_planar_curve());
    curves.curves.push_back(make_twisted_curve());
    curves.curves.push_back(nurbsreg::engine::make_circle(Vec3(0, 0, 0), 30.0));
    write(dir, "curves.json", curves);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
