#pragma once
// NumPy point arrays into the engine: an N×3 float64 or float32 array of any strides (C- or
// Fortran-ordered, sliced, transposed) is read in place through an engine::PointView, so the
// projection copies nothing. Calls that need contiguous float64 points (ICP's spans) ask for
// a copy with contiguous_finite(), which is free when the array already is one and has no
// NaN or infinite rows.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <span>
#include <vector>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::python {

namespace py = pybind11;

class PointsArg {
 public:
  // `name` names the argument in the errors: TypeError when `object` is neither an ndarray of
  // float64/float32 nor a nested sequence of numbers, ValueError when its shape is not (N, 3).
  // A non-array sequence is converted to a float64 array (a copy).
  PointsArg(const py::handle& object, const char* name);

  std::size_t size() const { return count_; }
  // In place; valid while this object lives. Callable without the GIL.
  engine::PointView view() const;
  // The array is C-contiguous, aligned float64: the engine's own layout (Vec3 per row).
  bool is_contiguous_double() const { return contiguous_double_; }

  // The finite rows as contiguous float64 points, and (when some were dropped) their row
  // numbers. Copies unless the array is contiguous float64 with every row finite: then `points`
  // views the array and `storage` and `rows` stay empty. Callable without the GIL.
  struct Finite {
    std::span<const engine::Vec3> points;
    std::vector<engine::Vec3> storage;
    std::vector<std::uint64_t> rows;  // empty: row i is point i
    std::size_t skipped = 0;          // rows with a NaN or infinite coordinate
  };
  Finite contiguous_finite() const;

  // Where row i, column k is: base + i * row_stride + k * column_stride (bytes).
  struct Layout {
    const char* base = nullptr;
    std::ptrdiff_t row_stride = 0, column_stride = 0;
  };

 private:
  py::array array_;  // keeps the data alive
  Layout layout_;
  std::size_t count_ = 0;
  bool single_ = false;  // float32
  bool contiguous_double_ = false;
};

}  // namespace nurbsreg::python
