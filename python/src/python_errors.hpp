#pragma once
// C++ errors as Python exceptions. The exception classes are defined in the pure-Python
// package (nurbsreg/_errors.py) and handed to the extension at import (_core._register_types):
// io::InputError -> nurbsreg.InputError (a ValueError), io::OutputError -> nurbsreg.OutputError
// (an OSError), each with the CLI's one-line message. (A failed alignment and the CLI's warnings
// come back in the results; the package raises nurbsreg.AlignmentError and calls warnings.warn.)

#include <pybind11/pybind11.h>

#include <string>

namespace nurbsreg::python {

namespace py = pybind11;

struct PythonTypes {
  py::object input_error;
  py::object output_error;
};

// The registered classes (None until nurbsreg/__init__.py registered them).
const PythonTypes& python_types();

// Binds _register_types and installs the C++ -> Python exception translator.
void bind_errors(py::module_& m);

}  // namespace nurbsreg::python
