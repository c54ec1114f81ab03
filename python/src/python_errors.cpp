#include "python_errors.hpp"

#include <stdexcept>

#include "nurbsreg/io/errors.hpp"

namespace nurbsreg::python {
namespace {

// Leaked on purpose: Python objects must not be released after the interpreter is gone.
PythonTypes& types() {
  static PythonTypes* t = new PythonTypes{py::none(), py::none()};
  return *t;
}

void set_error(const py::object& type, PyObject* fallback, const char* message) {
  PyErr_SetString(type.is_none() ? fallback : type.ptr(), message);
}

}  // namespace

const PythonTypes& python_types() {
  return types();
}

void bind_errors(py::module_& m) {
  m.def(
      "_register_types",
      [](py::object input_error, py::object output_error) {
        types() = PythonTypes{std::move(input_error), std::move(output_error)};
      },
      "Internal: the package's exception classes.");
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const io::InputError& e) {
      set_error(types().input_error, PyExc_ValueError, e.what());
    } catch (const io::OutputError& e) {
      set_error(types().output_error, PyExc_OSError, e.what());
    }
  });
}

}  // namespace nurbsreg::python
