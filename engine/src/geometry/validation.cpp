#include "geometry/validation.hpp"

#include <cmath>
#include <sstream>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine::detail {

std::string format_number(double x) {
  std::ostringstream out;
  out.precision(17);
  out << x;
  return out.str();
}

std::optional<std::string> check_degree(const char* field, int degree) {
  if (degree < 1 || degree > kMaxDegree) {
    return std::string(field) + ": must be between 1 and " + std::to_string(kMaxDegree) + " (got " +
           std::to_string(degree) + ")";
  }
  return std::nullopt;
}

std::optional<std::string> check_knots(const char* field, std::span<const double> knots, int degree,
                                       int count) {
  const std::string name(field);
  if (count < degree + 1) {
    return "control point count " + std::to_string(count) +
           " is less than degree + 1 = " + std::to_string(degree + 1);
  }
  const std::size_t expected = static_cast<std::size_t>(count + degree + 1);
  if (knots.size() != expected) {
    return name + ": expected " + std::to_string(expected) +
           " values (control points + degree + 1), got " + std::to_string(knots.size());
  }
  for (std::size_t i = 0; i < knots.size(); ++i) {
    if (!std::isfinite(knots[i])) return name + "[" + std::to_string(i) + "]: not a finite number";
    if (i > 0 && knots[i] < knots[i - 1]) {
      return name + ": decreasing at index " + std::to_string(i) + " (" + format_number(knots[i]) +
             " < " + format_number(knots[i - 1]) + ")";
    }
  }
  const double lo = knots[degree];
  const double hi = knots[count];
  if (!(lo < hi)) {
    return name + ": empty parameter domain [" + format_number(lo) + ", " + format_number(hi) + "]";
  }
  // Interior knots: strictly inside the domain. Multiplicity above the degree would make the
  // entity discontinuous there.
  std::size_t i = 0;
  while (i < knots.size()) {
    std::size_t j = i;
    while (j < knots.size() && knots[j] == knots[i])
      ++j;
    const int multiplicity = static_cast<int>(j - i);
    if (knots[i] > lo && knots[i] < hi && multiplicity > degree) {
      return name + ": interior knot " + format_number(knots[i]) + " has multiplicity " +
             std::to_string(multiplicity) + ", more than the degree " + std::to_string(degree);
    }
    i = j;
  }
  return std::nullopt;
}

}  // namespace nurbsreg::engine::detail
