#include "points_arg.hpp"

#include <cmath>
#include <cstring>
#include <string>

namespace nurbsreg::python {
namespace {

// memcpy: a strided or offset array need not be aligned for T (a plain load on x86).
template <class T>
double value_at(const char* p) {
  T x;
  std::memcpy(&x, p, sizeof(T));
  return static_cast<double>(x);
}

template <class T>
engine::Vec3 strided_point(const void* data, std::size_t i) {
  const auto* self = static_cast<const PointsArg::Layout*>(data);
  const char* p = self->base + static_cast<std::ptrdiff_t>(i) * self->row_stride;
  return {value_at<T>(p), value_at<T>(p + self->column_stride),
          value_at<T>(p + 2 * self->column_stride)};
}

std::string shape_text(const py::array& a) {
  std::string text = "(";
  for (py::ssize_t k = 0; k < a.ndim(); ++k)
    text += (k ? ", " : "") + std::to_string(a.shape(k));
  return text + (a.ndim() == 1 ? ",)" : ")");
}

}  // namespace

PointsArg::PointsArg(const py::handle& object, const char* name) {
  if (py::isinstance<py::array>(object)) {
    array_ = py::reinterpret_borrow<py::array>(object);
  } else {
    // Lists and tuples of numbers: numpy.asarray(object, dtype=float64), which raises for
    // ragged or non-numeric input.
    try {
      const py::module_ numpy = py::module_::import("numpy");
      array_ = numpy.attr("asarray")(object, py::arg("dtype") = numpy.attr("float64"));
    } catch (py::error_already_set&) {
      throw py::type_error(std::string(name) +
                           ": expected an (N, 3) float64 or float32 array, got " +
                           std::string(py::str(py::type::handle_of(object).attr("__name__"))));
    }
  }
  const py::dtype dtype = array_.dtype();
  const char kind = dtype.kind();
  const bool native = dtype.attr("isnative").cast<bool>();
  if (kind != 'f' || !native || (dtype.itemsize() != 8 && dtype.itemsize() != 4)) {
    throw py::type_error(std::string(name) + ": expected float64 or float32 values, got " +
                         dtype.attr("name").cast<std::string>() +
                         " (convert with .astype(numpy.float64))");
  }
  if (array_.ndim() != 2 || array_.shape(1) != 3) {
    throw py::value_error(std::string(name) + ": expected shape (N, 3), got " + shape_text(array_));
  }
  single_ = dtype.itemsize() == 4;
  count_ = static_cast<std::size_t>(array_.shape(0));
  layout_ = {static_cast<const char*>(array_.data()), array_.strides(0), array_.strides(1)};
  const bool aligned = (array_.flags() & py::detail::npy_api::NPY_ARRAY_ALIGNED_) != 0;
  contiguous_double_ = !single_ && aligned && layout_.column_stride == 8 &&
                       (layout_.row_stride == 24 || count_ <= 1);
}

engine::PointView PointsArg::view() const {
  if (contiguous_double_) {
    return engine::PointView::of(
        std::span<const engine::Vec3>(reinterpret_cast<const engine::Vec3*>(layout_.base), count_));
  }
  engine::PointView v;
  v.data = &layout_;
  v.count = count_;
  v.at = single_ ? &strided_point<float> : &strided_point<double>;
  return v;
}

PointsArg::Finite PointsArg::contiguous_finite() const {
  Finite f;
  const engine::PointView points = view();
  std::size_t finite = 0;
  for (std::size_t i = 0; i < count_; ++i)
    finite += points[i].allFinite() ? 1 : 0;
  f.skipped = count_ - finite;
  if (contiguous_double_ && f.skipped == 0) {
    f.points =
        std::span<const engine::Vec3>(reinterpret_cast<const engine::Vec3*>(layout_.base), count_);
    return f;
  }
  f.storage.reserve(finite);
  if (f.skipped > 0) f.rows.reserve(finite);
  for (std::size_t i = 0; i < count_; ++i) {
    const engine::Vec3 p = points[i];
    if (!p.allFinite()) continue;
    f.storage.push_back(p);
    if (f.skipped > 0) f.rows.push_back(i);
  }
  f.points = f.storage;
  return f;
}

}  // namespace nurbsreg::python
