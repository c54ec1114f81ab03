#pragma once
// Internal: where the clipping starts its Newton on the geometry: the minimiser of a 1-D
// Bernstein polynomial (a boundary row) and of a 2-D grid proven convex, by projected Newton on
// the coefficients. Starting points only: the geometric Newton does the real work.

namespace nurbsreg::engine {

// The minimiser of the polynomial with Bernstein coefficients c[0..count) on [0, 1], from u.
double bernstein_minimiser(const double* c, int count, double u);

// bernstein_minimiser_2d for the grids it is instantiated for (bicubic and biquadratic patches);
// false for any other grid (the start is left as it is).
bool polynomial_start(const double* a, int rows, int cols, double& u, double& v);

}  // namespace nurbsreg::engine
