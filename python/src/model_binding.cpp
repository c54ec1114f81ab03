// Model loading (io::read_model_file: JSON, STEP, IGES) and what `nurbsreg info --json` says of
// a model.

#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>

#include "bindings.hpp"
#include "model_handle.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/io/model_summary.hpp"
#include "nurbsreg/io/model_warnings.hpp"
#include "released_call.hpp"

namespace nurbsreg::python {
namespace {

py::array_t<double> vector3(const engine::Vec3& v) {
  py::array_t<double> a(3);
  for (int k = 0; k < 3; ++k)
    a.mutable_at(k) = v[k];
  return a;
}

}  // namespace

void bind_model(py::module_& m) {
  py::class_<ModelHandle, ModelPtr>(m, "Model",
                                    "A loaded, prepared model (immutable; shared by any number "
                                    "of threads and calls).")
      .def_property_readonly("path", &ModelHandle::path, "The file it was loaded from.")
      .def_property_readonly(
          "units", [](const ModelHandle& h) { return h.model().units; },
          "Length unit of the model (\"mm\" for STEP/IGES: OpenCASCADE converts on reading).")
      .def_property_readonly("surface_count",
                             [](const ModelHandle& h) { return h.model().surfaces.size(); })
      .def_property_readonly("curve_count",
                             [](const ModelHandle& h) { return h.model().curves.size(); })
      .def_property_readonly("patch_count",
                             [](const ModelHandle& h) { return h.prepared().patch_count(); })
      .def_property_readonly(
          "bounds",
          [](const ModelHandle& h) {
            const engine::Aabb& box = h.prepared().geometry_bounds().box;
            return py::make_tuple(vector3(box.lo), vector3(box.hi));
          },
          "(min, max) corners of the model's bounding box: its faces as trimmed, their edges and "
          "its curves (info()[\"bounding_box\"], a proven bound; "
          "info()[\"bounding_box_kind\"] says whether it is exact).")
      .def_property_readonly(
          "control_point_box",
          [](const ModelHandle& h) {
            return py::make_tuple(vector3(h.prepared().bounds().lo),
                                  vector3(h.prepared().bounds().hi));
          },
          "(min, max) corners of the box of every control point, trimmed away or not "
          "(info()[\"control_point_box\"]): far larger than bounds where faces are small pieces "
          "of large surfaces.")
      .def(
          "info",
          [](const ModelHandle& h) {
            const std::string text =
                io::model_summary_to_json(io::summarize_model(h.model(), h.prepared()));
            return py::module_::import("json").attr("loads")(text);
          },
          "What `nurbsreg info --json` says of the model, as a dict: units, surfaces (faces: "
          "degrees, control points, Bézier patches, domains, boxes, trimming), curves, "
          "bezier_patches, bezier_curve_pieces, bounding_box {min, max}, trimmed_surfaces, "
          "skipped_faces [{face, reason}].")
      .def_property_readonly(
          "warnings", [](const ModelHandle& h) { return io::model_warnings(h.path(), h.model()); },
          "The CLI's warnings about this model (missing faces).")
      .def("__repr__", [](const ModelHandle& h) {
        return "<nurbsreg.Model " + h.path() + ": " + std::to_string(h.model().surfaces.size()) +
               " surfaces, " + std::to_string(h.model().curves.size()) + " curves, " +
               std::to_string(h.prepared().patch_count()) + " Bézier patches, " + h.model().units +
               ">";
      });

  m.def(
      "load_model",
      [](const std::filesystem::path& path) {
        ModelPtr handle;
        run_released(0, false, [&] {
          const std::string name = path.string();
          handle = std::make_shared<ModelHandle>(name, io::read_model_file(name));
        });
        return handle;
      },
      py::arg("path"));
}

}  // namespace nurbsreg::python
