#include "bernstein/de_casteljau.hpp"

#include "platform/cpu_dispatch.hpp"

namespace nurbsreg::engine {

NURBSREG_HOT_CLONES
void split_rows(double* low, double* high, int rows, int cols) {
  for (int j = 0; j < cols; ++j)
    halve(low + j, cols, rows - 1, low + j, high + j);
}

NURBSREG_HOT_CLONES
void split_line(double* low, double* high, int count) {
  halve(low, 1, count - 1, low, high);
}

}  // namespace nurbsreg::engine
