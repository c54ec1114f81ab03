#include "model_ranges.hpp"

#include <cmath>
#include <optional>
#include <span>

#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/input_ranges.hpp"
#include "nurbsreg/io/resource_limits.hpp"
#include "text_io.hpp"

namespace nurbsreg::io::detail {
namespace {

using text_detail::format_number;

// The first problem of one knot vector, or nothing.
std::optional<std::string> knot_problem(const std::string& field, std::span<const double> knots) {
  for (std::size_t i = 0; i < knots.size(); ++i) {
    if (std::abs(knots[i]) > kMaxKnot) {
      return field + "[" + std::to_string(i) + "] = " + format_number(knots[i]) +
             " is beyond the supported parameter range |knot| <= 1e15";
    }
    if (i > 0 && knots[i] > knots[i - 1] && knots[i] - knots[i - 1] < kMinKnotSpan) {
      return field + "[" + std::to_string(i) + "]: knot span " +
             format_number(knots[i] - knots[i - 1]) +
             " is narrower than the supported 1e-40 (derivatives would overflow)";
    }
  }
  return std::nullopt;
}

std::optional<std::string> point_problem(const std::string& field, const engine::Vec3& p,
                                         int dimension) {
  for (int axis = 0; axis < dimension; ++axis) {
    if (std::abs(p[axis]) > kMaxCoordinate) {
      return field + ": coordinate " + std::to_string(axis) + " = " + format_number(p[axis]) +
             " is beyond the supported range |coordinate| <= 1e15";
    }
  }
  return std::nullopt;
}

std::optional<std::string> weight_problem(const std::string& field, double w) {
  if (w < kMinWeight || w > kMaxWeight) {
    return field + " = " + format_number(w) + " is outside the supported range [1e-10, 1e10]";
  }
  return std::nullopt;
}

std::optional<std::string> curve_problem(const engine::NurbsCurve& c) {
  if (auto p = knot_problem("knots", c.knots)) return p;
  for (std::size_t i = 0; i < c.control_points.size(); ++i) {
    if (auto p = point_problem("control_points[" + std::to_string(i) + "]", c.control_points[i],
                               c.dimension)) {
      return p;
    }
  }
  for (std::size_t i = 0; i < c.weights.size(); ++i) {
    if (auto p = weight_problem("weights[" + std::to_string(i) + "]", c.weights[i])) return p;
  }
  return std::nullopt;
}

std::optional<std::string> surface_problem(const engine::NurbsSurface& s) {
  if (auto p = knot_problem("knots_u", s.knots_u)) return p;
  if (auto p = knot_problem("knots_v", s.knots_v)) return p;
  for (int i = 0; i < s.count_u; ++i) {
    for (int j = 0; j < s.count_v; ++j) {
      const std::string at = "[" + std::to_string(i) + "][" + std::to_string(j) + "]";
      if (auto p = point_problem("control_points" + at, s.point(i, j), 3)) return p;
      if (s.is_rational()) {
        if (auto p = weight_problem("weights" + at, s.weight(i, j))) return p;
      }
    }
  }
  for (std::size_t l = 0; l < s.trim_loops.size(); ++l) {
    for (std::size_t k = 0; k < s.trim_loops[l].curves.size(); ++k) {
      const engine::TrimCurve& t = s.trim_loops[l].curves[k];
      const std::string at =
          "trim_loops[" + std::to_string(l) + "].curves[" + std::to_string(k) + "].";
      if (auto p = curve_problem(t.uv)) return at + "uv." + *p;
      if (t.edge) {
        if (auto p = curve_problem(*t.edge)) return at + "edge." + *p;
      }
    }
  }
  return std::nullopt;
}

std::string label(const char* kind, std::size_t index, const std::string& name) {
  std::string out = std::string(kind) + " " + std::to_string(index);
  if (!name.empty()) out += " " + text_detail::quote_name(name);
  return out;
}

// Non-empty knot spans inside the domain [knots[degree], knots[count]]: the Bézier pieces the
// decomposition makes along this direction.
std::uint64_t pieces(std::span<const double> knots, int degree) {
  std::uint64_t n = 0;
  const std::size_t count = knots.size() - static_cast<std::size_t>(degree) - 1;
  for (std::size_t i = static_cast<std::size_t>(degree); i < count; ++i) {
    if (knots[i + 1] > knots[i]) ++n;
  }
  return n;
}

}  // namespace

void check_model_ranges(const engine::Model& model, const std::string& file) {
  for (std::size_t i = 0; i < model.surfaces.size(); ++i) {
    if (auto p = surface_problem(model.surfaces[i])) {
      throw InputError(file, label("surface", i, model.surfaces[i].name) + ": " + *p +
                                 " (README \"Coordinate range\")");
    }
  }
  for (std::size_t i = 0; i < model.curves.size(); ++i) {
    if (auto p = curve_problem(model.curves[i])) {
      throw InputError(file, label("curve", i, model.curves[i].name) + ": " + *p +
                                 " (README \"Coordinate range\")");
    }
  }
}

void check_model_size(const engine::Model& model, const std::string& file) {
  // Counted in floating point: a hostile model's product of spans must not wrap.
  double total = 0, patches = 0;
  double largest = 0;
  std::size_t largest_index = 0;
  for (std::size_t i = 0; i < model.surfaces.size(); ++i) {
    const engine::NurbsSurface& s = model.surfaces[i];
    const double n = static_cast<double>(pieces(s.knots_u, s.degree_u)) *
                     static_cast<double>(pieces(s.knots_v, s.degree_v));
    const double points = n * (s.degree_u + 1) * (s.degree_v + 1);
    patches += n;
    total += points;
    if (points > largest) {
      largest = points;
      largest_index = i;
    }
  }
  for (const engine::NurbsCurve& c : model.curves) {
    total += static_cast<double>(pieces(c.knots, c.degree)) * (c.degree + 1);
  }
  const std::uint64_t limit = resource_limits().max_bezier_points;
  if (total <= static_cast<double>(limit)) return;
  std::string detail;
  if (!model.surfaces.empty()) {
    const engine::NurbsSurface& s = model.surfaces[largest_index];
    detail = "; the largest, " + label("surface", largest_index, s.name) + ", has " +
             std::to_string(pieces(s.knots_u, s.degree_u)) + " x " +
             std::to_string(pieces(s.knots_v, s.degree_v)) + " patches of degree (" +
             std::to_string(s.degree_u) + ", " + std::to_string(s.degree_v) + ")";
  }
  throw InputError(file, "the model decomposes into " + format_number(patches) +
                             " Bezier patches with " + format_number(total) +
                             " control points in all, more than the limit of " +
                             std::to_string(limit) + " (about 60 bytes each once prepared)" +
                             detail + "; raise it with NURBSREG_MAX_BEZIER_POINTS=<n>");
}

}  // namespace nurbsreg::io::detail
