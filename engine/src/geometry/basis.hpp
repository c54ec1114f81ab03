#pragma once
// B-spline basis functions (The NURBS Book, A2.1-A2.3). No allocation: callers pass fixed-size
// arrays sized by kMaxDegree.

#include <span>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine {

// Highest derivative order the evaluators provide.
inline constexpr int kMaxDerivative = 2;

// A2.1: the knot span index i with knots[i] <= u < knots[i+1], restricted to the curve's
// domain [knots[degree], knots[count]] (count = number of control points). u outside the
// domain is clamped to it; u == the domain end maps to the last non-empty span.
int find_span(int degree, std::span<const double> knots, int count, double u);

// A2.2: the degree+1 non-zero basis functions N[span-degree .. span] at u, into values[0..degree].
void basis_functions(int span, double u, int degree, std::span<const double> knots, double* values);

// A2.3: derivatives of the non-zero basis functions up to order n (n <= kMaxDerivative):
// ders[k][j] = d^k/du^k N_{span-degree+j}(u).
void basis_derivatives(int span, double u, int degree, std::span<const double> knots, int n,
                       double (*ders)[kMaxDegree + 1]);

}  // namespace nurbsreg::engine
