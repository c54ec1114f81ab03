// nurbsreg._core: the compiled half of the `nurbsreg` package (python/nurbsreg/__init__.py is
// the other).

#include <pybind11/pybind11.h>

#include "bindings.hpp"
#include "python_errors.hpp"
#include "released_call.hpp"

#ifndef NURBSREG_VERSION
#define NURBSREG_VERSION "unknown"
#endif

namespace nurbsreg::python {

int thread_count(const std::optional<int>& threads) {
  if (!threads) return 0;
  if (*threads < 0)
    throw py::value_error("threads: must be >= 0 (0 or None = all hardware threads)");
  return *threads;
}

}  // namespace nurbsreg::python

PYBIND11_MODULE(_core, m) {
  using namespace nurbsreg::python;
  m.doc() = "nurbsreg's compiled bindings; use the `nurbsreg` package, not this module.";
  m.attr("__version__") = NURBSREG_VERSION;
  init_released_calls();
  bind_errors(m);
  bind_model(m);
  bind_projection(m);
  bind_alignment(m);
  bind_point_io(m);
  bind_inspect(m);
}
