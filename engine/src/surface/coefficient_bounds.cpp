#include "surface/coefficient_bounds.hpp"

#include <algorithm>
#include <limits>

#include "platform/cpu_dispatch.hpp"
#include "platform/vector_lanes.hpp"

namespace nurbsreg::engine {

NURBSREG_HOT_CLONES
CoefficientRange coefficient_range(const double* n, const double* d, int count, bool rational) {
  CoefficientRange r{std::numeric_limits<double>::infinity(),
                     -std::numeric_limits<double>::infinity(), 0};
  // The minimum and maximum only, in vector lanes (order-independent; a NaN is ignored, as
  // std::min and std::max ignore it). A rational patch's ratios N_k / D_k are divided in the lanes
  // too: IEEE division is correctly rounded, so each lane's quotient is the scalar one. The index
  // of the minimum is wanted only where a box ends in Newton: arg = -1, and first_index_of (or
  // first_ratio_index_of) finds it then, the first index holding the minimum.
  SlotRange<kLanes> lanes;
  int k = 0;
  if (!rational) {
    for (; k + kLanes <= count; k += kLanes)
      lanes.add(0, load_lanes(n + k));
  } else {
    for (; k + kLanes <= count; k += kLanes)
      lanes.add(0, load_lanes(n + k) / load_lanes(d + k));
  }
  Iv range = lanes.reduce();
  for (; k < count; ++k) {
    const double f = rational ? n[k] / d[k] : n[k];
    range.lo = std::min(range.lo, f);
    range.hi = std::max(range.hi, f);
  }
  r.lo = range.lo;
  r.hi = range.hi;
  r.arg = -1;
  return r;
}

NURBSREG_HOT_CLONES
int boundary_edge(const double* f, int rows, int cols) {
  // The edge's own row (column) is skipped (x < x is false, also for NaN), and the others are
  // compared nearest first: where the test fails, F usually falls just inside the edge. The
  // order of the comparisons does not change the answer.
  auto row_below = [&](int r) {
    const double* edge = f + r * cols;
    for (int k = 1; k < rows; ++k) {
      const double* row = f + (r == 0 ? k : rows - 1 - k) * cols;
      for (int j = 0; j < cols; ++j) {
        if (row[j] < edge[j]) return false;
      }
    }
    return true;
  };
  auto col_below = [&](int c) {
    for (int k = 1; k < cols; ++k) {
      const int j = c == 0 ? k : cols - 1 - k;
      for (int i = 0; i < rows; ++i) {
        if (f[i * cols + j] < f[i * cols + c]) return false;
      }
    }
    return true;
  };
  if (row_below(0)) return 0;
  if (row_below(rows - 1)) return 1;
  if (col_below(0)) return 2;
  if (col_below(cols - 1)) return 3;
  return -1;
}

}  // namespace nurbsreg::engine
