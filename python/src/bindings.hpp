#pragma once
// The pieces of the extension module nurbsreg._core, one file each. The public API, its
// docstrings and argument checks of plain Python values live in the package (nurbsreg/*.py);
// these bind the library calls the CLI makes, so that every answer is the CLI's.

#include <pybind11/pybind11.h>

#include <optional>
#include <string>

namespace nurbsreg::python {

namespace py = pybind11;

void bind_model(py::module_& m);
void bind_projection(py::module_& m);
void bind_alignment(py::module_& m);
void bind_point_io(py::module_& m);
void bind_inspect(py::module_& m);

// threads= of every call: None or 0 = all hardware threads, else that many (ValueError below 0).
int thread_count(const std::optional<int>& threads);

// Calls with at least this many points run watched (run_released): Ctrl-C stops them. Below it
// the hand-over to a helper thread would cost more than the call.
inline constexpr std::size_t kWatchedPoints = 20000;

}  // namespace nurbsreg::python
