#include "bernstein/de_casteljau.hpp"

#include <cstring>

#include "platform/cpu_dispatch.hpp"

namespace nurbsreg::engine {

// halve() on every column, a whole row at a time: `high` is the work array (its row i holds
// work[i] of every column), so each level is one contiguous pass over the rows it updates, in
// vector lanes. Every element takes the same operations in the same order as halve() on its
// column (0.5 (x + y) of the same two values): bit-identical. After level r, the work's row 0 is
// the low half's row r, and its row rows - 1 - r is final (the high half's row; later levels do
// not reach it).
NURBSREG_HOT_CLONES
void split_rows(double* low, double* high, int rows, int cols) {
  const int n = rows - 1;
  std::memcpy(high, low, sizeof(double) * rows * cols);
  for (int r = 1; r <= n; ++r) {
    const int count = (n - r + 1) * cols;
    for (int k = 0; k < count; ++k)
      high[k] = 0.5 * (high[k] + high[k + cols]);
    std::memcpy(low + r * cols, high, sizeof(double) * cols);
  }
}

NURBSREG_HOT_CLONES
void split_rows_at(double* low, double* high, int rows, int cols, double x) {
  const int n = rows - 1;
  const double y = 1.0 - x;
  std::memcpy(high, low, sizeof(double) * rows * cols);
  for (int r = 1; r <= n; ++r) {
    const int count = (n - r + 1) * cols;
    for (int k = 0; k < count; ++k)
      high[k] = y * high[k] + x * high[k + cols];
    std::memcpy(low + r * cols, high, sizeof(double) * cols);
  }
}

// split_line on every row, all rows at once: the grid is copied column-major into `work` (column
// j at work + j * rows, so that work's "row" j holds work[j] of every grid row) and halved as
// split_rows halves, one contiguous pass per level over all the grid's rows; each level's two
// finished columns are written back. Every element takes split_line's operations in its order:
// bit-identical.
NURBSREG_HOT_CLONES
void split_cols(double* low, double* high, int rows, int cols) {
  const int n = cols - 1;
  double work[kMaxGridSide * kMaxGridSide];
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j)
      work[j * rows + i] = low[i * cols + j];
  }
  for (int i = 0; i < rows; ++i)
    high[i * cols + n] = low[i * cols + n];
  for (int r = 1; r <= n; ++r) {
    const int count = (n - r + 1) * rows;
    for (int k = 0; k < count; ++k)
      work[k] = 0.5 * (work[k] + work[k + rows]);
    const double* finished = work + (n - r) * rows;
    for (int i = 0; i < rows; ++i) {
      low[i * cols + r] = work[i];
      high[i * cols + n - r] = finished[i];
    }
  }
}

NURBSREG_HOT_CLONES
void split_line(double* low, double* high, int count) {
  halve(low, 1, count - 1, low, high);
}

}  // namespace nurbsreg::engine
