#pragma once
// Internal: the clipping's tests on the coefficient grid of F on a box: the range of the
// coefficient ratios N_k / D_k (Theorem 1 of seed 001: F's range on the box) and Theorem 2's
// boundary edge.

namespace nurbsreg::engine {

// Smallest and largest coefficient ratio N_k / D_k and the index of the smallest, in one pass.
struct CoefficientRange {
  double lo, hi;
  int arg;
};

// arg is -1: first_index_of (rational: first_ratio_index_of) finds it when it is wanted.
CoefficientRange coefficient_range(const double* n, const double* d, int count, bool rational);

// The first index k with a[k] == value (0 if none): the arg of coefficient_range's minimum.
inline int first_index_of(const double* a, int count, double value) {
  for (int k = 0; k < count; ++k) {
    if (a[k] == value) return k;
  }
  return 0;
}

// The first index k with n[k] / d[k] == value (0 if none): a rational coefficient_range's arg.
inline int first_ratio_index_of(const double* n, const double* d, int count, double value) {
  for (int k = 0; k < count; ++k) {
    if (n[k] / d[k] == value) return k;
  }
  return 0;
}

// Theorem 2 of seed 001 for a polynomial F: if the coefficients of one boundary row (column) are
// below every coefficient of their column (row), F attains its minimum over the box on that edge.
// Returns 0: s = s0, 1: s = s1, 2: t = t0, 3: t = t1, or -1. Not used for rational patches: the
// proof compares F with F(u0, v) through the same Bernstein weights, which a rational F (weights
// B D_ij / Σ B D) does not share, so it does not carry over.
int boundary_edge(const double* f, int rows, int cols);

}  // namespace nurbsreg::engine
