#pragma once
// Shared checks for validate(): each returns a message naming the field, or nothing.

#include <optional>
#include <span>
#include <string>

namespace nurbsreg::engine::detail {

std::optional<std::string> check_degree(const char* field, int degree);
// Non-decreasing, finite, expected size, non-empty domain, interior multiplicity <= degree.
std::optional<std::string> check_knots(const char* field, std::span<const double> knots, int degree,
                                       int count);
std::string format_number(double x);

}  // namespace nurbsreg::engine::detail
