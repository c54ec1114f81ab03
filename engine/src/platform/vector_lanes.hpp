#pragma once
// Internal: the GCC vector type the hot kernels of the clipping use (two doubles in a portable
// build, four where AVX is enabled), and a running minimum and maximum over its lanes.
// Element-wise IEEE operations only: results do not depend on the lane count.

#include <algorithm>
#include <cstring>
#include <limits>

namespace nurbsreg::engine {
namespace {

// A closed range [lo, hi]. Rounding is covered by the relative margins of the tests using it.
struct Iv {
  double lo, hi;
};

// The fixed-degree kernel below works on W doubles at a time (GCC vector extension: element-wise
// IEEE operations, one SSE2 or AVX register): W = 4 does the four homogeneous coordinates in one
// pass where AVX is enabled, W = 2 does (x, y) and then (z, w). Each coordinate sees exactly the
// operations of tensor_derivatives + rational_from_homogeneous in the same order (products, then
// sums from zero in index order; the same quotient-rule expressions, or the same unit-weight
// shortcut), so the results are bit-identical to them; only the schedule differs: one half of
// the accumulators at a time fits the 16 SSE registers, where the Vec4 form spilled to the
// stack.
#if defined(__AVX__)
constexpr int kLanes = 4;
#else
constexpr int kLanes = 2;
#endif
typedef double Lanes __attribute__((vector_size(sizeof(double) * kLanes)));

inline Lanes load_lanes(const double* x) {
  Lanes v;
  std::memcpy(&v, x, sizeof v);
  return v;
}

inline void store_lanes(double* x, Lanes v) {
  std::memcpy(x, &v, sizeof v);
}

// W doubles in one vector (patch_derivatives_fixed is instantiated for kLanes and, in the AVX2
// version of patch_derivatives, for 4). Loaded and stored through references and memcpy only:
// a 32-byte vector passed by value outside AVX code would change the ABI (-Wpsabi).
template <int W>
struct LanesOf;
template <>
struct LanesOf<2> {
  typedef double type __attribute__((vector_size(2 * sizeof(double))));
};
template <>
struct LanesOf<4> {
  typedef double type __attribute__((vector_size(4 * sizeof(double))));
};

// Running minimum and maximum of L values per slot, the first L - L % kLanes slots in vector
// lanes. add(j, x) folds x into slots [j, j + kLanes) (j a multiple of kLanes below the vector
// part's end); add_scalar(j, x) into slot j of the rest. min/max as std::min(acc, x) and
// std::max(acc, x) per slot (a NaN x is ignored, as there).
template <int L>
struct SlotRange {
  static constexpr int kVec = L / kLanes;
  static constexpr int kRest = L % kLanes;
  Lanes lo[kVec > 0 ? kVec : 1], hi[kVec > 0 ? kVec : 1];
  double rest_lo[kRest > 0 ? kRest : 1], rest_hi[kRest > 0 ? kRest : 1];
  SlotRange() {
    const double inf = std::numeric_limits<double>::infinity();
    Lanes plus, minus;
    for (int k = 0; k < kLanes; ++k) {
      plus[k] = inf;
      minus[k] = -inf;
    }
    for (int v = 0; v < kVec; ++v) {
      lo[v] = plus;
      hi[v] = minus;
    }
    for (int k = 0; k < kRest; ++k) {
      rest_lo[k] = inf;
      rest_hi[k] = -inf;
    }
  }
  void add(int v, Lanes x) {
    lo[v] = x < lo[v] ? x : lo[v];
    hi[v] = hi[v] < x ? x : hi[v];
  }
  void add_scalar(int k, double x) {
    rest_lo[k] = std::min(rest_lo[k], x);
    rest_hi[k] = std::max(rest_hi[k], x);
  }
  Iv reduce() const {
    double l = std::numeric_limits<double>::infinity(), h = -l;
    for (int v = 0; v < kVec; ++v) {
      for (int k = 0; k < kLanes; ++k) {
        l = std::min(l, lo[v][k]);
        h = std::max(h, hi[v][k]);
      }
    }
    for (int k = 0; k < kRest; ++k) {
      l = std::min(l, rest_lo[k]);
      h = std::max(h, rest_hi[k]);
    }
    return {l, h};
  }
};

}  // namespace
}  // namespace nurbsreg::engine
