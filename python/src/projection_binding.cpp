// project(): engine::Projector over a NumPy frame, results handed back as read-only NumPy views
// of the engine's own arrays (no copy on the way out either).

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <limits>

#include "bindings.hpp"
#include "model_handle.hpp"
#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/registration/scan_size.hpp"
#include "points_arg.hpp"
#include "released_call.hpp"

namespace nurbsreg::python {
namespace {

// One projected frame; the NumPy arrays handed out view its vectors and keep it alive.
struct ProjectionFrame {
  ModelPtr model;
  engine::ProjectionTarget target = engine::ProjectionTarget::surfaces;
  engine::ProjectionResults results;
  std::size_t skipped = 0;  // status skipped_nonfinite
  std::vector<std::string> warnings;
};
using FramePtr = std::shared_ptr<ProjectionFrame>;

void make_read_only(py::array& a) {
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
}

// A read-only view of `count` rows of `columns` values of type T starting at `data`, owned by
// `owner` (the Python ProjectionResult).
template <class T>
py::array view(const void* data, std::size_t count, std::size_t columns, py::handle owner) {
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(count)};
  std::vector<py::ssize_t> strides{static_cast<py::ssize_t>(columns * sizeof(T))};
  if (columns > 1) {
    shape.push_back(static_cast<py::ssize_t>(columns));
    strides.push_back(sizeof(T));
  }
  // numpy needs a non-null pointer for a view; an empty frame's vectors may have none.
  static const T none[3] = {};
  py::array a(py::dtype::of<T>(), shape, strides, data != nullptr ? data : none, owner);
  make_read_only(a);
  return a;
}

engine::ProjectionTarget parse_target(const std::string& target) {
  if (target == "surfaces") return engine::ProjectionTarget::surfaces;
  if (target == "curves") return engine::ProjectionTarget::curves;
  throw py::value_error("target: expected \"surfaces\" or \"curves\", got \"" + target + "\"");
}

FramePtr project(const ModelPtr& model, const py::handle& points_object, const std::string& target,
                 const std::optional<int>& threads, bool certify, const FramePtr& hints) {
  const PointsArg points(points_object, "points");
  auto frame = std::make_shared<ProjectionFrame>();
  frame->model = model;
  frame->target = parse_target(target);
  const engine::Model& m = model->model();
  // The CLI's usage errors (check_projection_target).
  if (frame->target == engine::ProjectionTarget::surfaces && m.surfaces.empty()) {
    throw py::value_error(model->path() + ": the model has no surfaces; use target=\"curves\"");
  }
  if (frame->target == engine::ProjectionTarget::curves && m.curves.empty()) {
    throw py::value_error(model->path() + ": the model has no curves; use target=\"surfaces\"");
  }
  if (hints) {
    if (hints->model != model) throw py::value_error("hints: a result of another model");
    if (hints->results.size() != points.size()) {
      throw py::value_error("hints: " + std::to_string(hints->results.size()) + " results for " +
                            std::to_string(points.size()) + " points");
    }
  }
  const int thread_limit = thread_count(threads);
  engine::ProjectionOptions options;
  options.target = frame->target;
  options.certify = certify;
  double scan_diagonal = 0.0;
  run_released(thread_limit, points.size() >= kWatchedPoints, [&] {
    const engine::PointView view = points.view();
    const ModelHandle::Lease projector = model->lease_projector();
    engine::HintView hint_view;
    if (hints) {
      hint_view = engine::HintView(
          &hints->results, hints->results.size(), [](const void* d, std::size_t i) {
            return static_cast<const engine::ProjectionResults*>(d)->hint(i);
          });
    }
    (*projector).project(view, options, frame->results, hint_view);
    for (std::size_t i = 0; i < frame->results.size(); ++i) {
      if (frame->results.status[i] == engine::ProjectionStatus::skipped_nonfinite) ++frame->skipped;
    }
    scan_diagonal = registration::scan_diagonal(view);
  });
  // The CLI's warning for a scan far larger or smaller than the model (registration::scan_size
  // on the finite points, against the trimmed faces' box as there).
  const double model_size = registration::model_size(model->prepared());
  const registration::ScanSize sizes{scan_diagonal, model_size, m.units};
  if (const auto note = sizes.warning()) frame->warnings.push_back("points: " + *note);
  // And the CLI's warning for points that mostly lie far from the model (not in its frame).
  if (const auto note =
          registration::far_from_model_note(frame->results.distance, model_size, m.units)) {
    frame->warnings.push_back("points: " + *note);
  }
  return frame;
}

}  // namespace

void bind_projection(py::module_& m) {
  using engine::FrameVector;
  using engine::Vec3;
  py::class_<ProjectionFrame, FramePtr> result(
      m, "ProjectionResult",
      "The exact closest points of a frame, one row per input point (read-only NumPy views).");
  const auto column = [&result](const char* name, auto member, const char* doc) {
    result.def_property_readonly(
        name,
        [member](py::object self) {
          const auto& f = self.cast<const ProjectionFrame&>();
          const auto& values = f.results.*member;
          using T = typename std::decay_t<decltype(values)>::value_type;
          if constexpr (std::is_same_v<T, Vec3>) {
            return view<double>(values.empty() ? nullptr : values.front().data(), values.size(), 3,
                                self);
          } else if constexpr (std::is_enum_v<T>) {
            return view<std::underlying_type_t<T>>(values.data(), values.size(), 1, self);
          } else {
            return view<T>(values.data(), values.size(), 1, self);
          }
        },
        doc);
  };
  using R = engine::ProjectionResults;
  column("foot", &R::foot, "(N, 3) float64: the closest point (NaN for skipped points).");
  column("distance", &R::distance, "(N,) float64: Euclidean distance >= 0 (NaN if skipped).");
  column("signed_distance", &R::signed_distance,
         "(N,) float64: > 0 on the side the normal points to.");
  column("entity", &R::entity, "(N,) int32: surface (or curve) index in the model, -1 if none.");
  column("u", &R::u, "(N,) float64: parameter u of the foot.");
  column("v", &R::v, "(N,) float64: parameter v of the foot (0 for curves).");
  column("normal", &R::normal, "(N, 3) float64: unit outer normal at the foot (0 for curves).");
  column("status", &R::status,
         "(N,) uint8: 0 ok, 1 skipped (NaN or infinite point), 2 no geometry, 3 beyond the maximum "
         "distance.");
  column("on_trim_edge", &R::on_trim_edge, "(N,) uint8: 1 when the foot is on a trim edge.");
  result
      .def_property_readonly(
          "skipped", [](const ProjectionFrame& f) { return f.skipped; },
          "Points skipped for a NaN or infinite coordinate.")
      .def_property_readonly("target",
                             [](const ProjectionFrame& f) {
                               return f.target == engine::ProjectionTarget::surfaces ? "surfaces"
                                                                                     : "curves";
                             })
      .def_property_readonly("warnings", [](const ProjectionFrame& f) { return f.warnings; })
      .def("__len__", [](const ProjectionFrame& f) { return f.results.size(); })
      .def("__repr__", [](const ProjectionFrame& f) {
        return "<nurbsreg.ProjectionResult: " + std::to_string(f.results.size()) + " points, " +
               std::to_string(f.skipped) + " skipped>";
      });

  m.def("project", &project, py::arg("model"), py::arg("points"), py::arg("target"),
        py::arg("threads"), py::arg("certify"), py::arg("hints"));
}

}  // namespace nurbsreg::python
