// Point-cloud files as arrays (io::read_point_cloud / io::write_point_cloud: PCD, PLY, XYZ) and
// synthetic scans (engine::make_synthetic_scan with the options of `nurbsreg synth`).

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>

#include "bindings.hpp"
#include "model_handle.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "points_arg.hpp"
#include "released_call.hpp"

namespace nurbsreg::python {
namespace {

// An (N, 3) float64 array that takes over `points` (no copy) and frees them with the array.
py::array_t<double> take_points(std::vector<engine::Vec3>&& points) {
  auto* owned = new std::vector<engine::Vec3>(std::move(points));
  const py::capsule free_points(owned,
                                [](void* p) { delete static_cast<std::vector<engine::Vec3>*>(p); });
  static const double none[3] = {};
  return py::array_t<double>({static_cast<py::ssize_t>(owned->size()), py::ssize_t{3}},
                             owned->empty() ? none : owned->front().data(), free_points);
}

template <class T>
py::array_t<T> take_vector(std::vector<T>&& values) {
  auto* owned = new std::vector<T>(std::move(values));
  const py::capsule free_values(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  static const T none{};
  return py::array_t<T>(static_cast<py::ssize_t>(owned->size()),
                        owned->empty() ? &none : owned->data(), free_values);
}

py::dict read_cloud(const std::filesystem::path& path) {
  io::PointCloud cloud;
  run_released(0, false, [&] { cloud = io::read_point_cloud(path.string()); });
  py::dict out;
  out["skipped"] = cloud.skipped_nonfinite;
  out["total"] = cloud.total;
  out["width"] = cloud.width;
  out["height"] = cloud.height;
  out["points"] = take_points(std::move(cloud.points));
  out["index"] = take_vector(std::move(cloud.source_index));
  return out;
}

io::PcdEncoding parse_encoding(const std::string& encoding) {
  if (encoding == "binary") return io::PcdEncoding::binary;
  if (encoding == "ascii") return io::PcdEncoding::ascii;
  if (encoding == "binary_compressed") return io::PcdEncoding::binary_compressed;
  throw py::value_error(
      "encoding: expected \"binary\", \"ascii\" or \"binary_compressed\", got \"" + encoding +
      "\"");
}

void write_cloud(const std::filesystem::path& path, const py::handle& points_object,
                 const std::string& encoding, bool double_precision) {
  const PointsArg points(points_object, "points");
  io::PointCloudWriteOptions options;
  options.pcd_encoding = parse_encoding(encoding);
  options.double_precision = double_precision;
  run_released(0, false, [&] {
    std::vector<engine::Vec3> copy;
    std::span<const engine::Vec3> rows;
    if (points.is_contiguous_double()) {
      rows = {static_cast<const engine::Vec3*>(points.view().data), points.size()};
    } else {
      const engine::PointView view = points.view();
      copy.resize(points.size());
      for (std::size_t i = 0; i < copy.size(); ++i)
        copy[i] = view[i];
      rows = copy;
    }
    io::write_point_cloud(path.string(), rows, options);
  });
}

py::dict synth(const ModelPtr& model, std::size_t points, double noise,
               const std::optional<std::array<double, 6>>& pose, std::uint64_t seed,
               double outliers, double view_fraction, const std::array<double, 3>& view_direction,
               double fixture, const std::array<double, 3>& fixture_up) {
  if (model->model().surfaces.empty()) {
    throw py::value_error(model->path() + ": synth needs a model with surfaces");
  }
  if (points == 0) throw py::value_error("points: must be > 0");
  engine::SyntheticScanOptions options;
  options.points = points;
  options.noise_sigma = noise;
  options.seed = seed;
  options.outlier_fraction = outliers;
  options.view_fraction = view_fraction;
  options.view_direction = engine::Vec3(view_direction[0], view_direction[1], view_direction[2]);
  options.fixture_fraction = fixture;
  options.fixture_up = engine::Vec3(fixture_up[0], fixture_up[1], fixture_up[2]);
  if (pose) {
    const auto& p = *pose;
    options.T_scan_model =
        engine::pose_from_euler_degrees(p[0], p[1], p[2], engine::Vec3(p[3], p[4], p[5]));
  }
  if (auto error = options.validate()) throw py::value_error(*error);
  engine::SyntheticScan scan;
  run_released(0, false, [&] { scan = engine::make_synthetic_scan(model->model(), options); });
  py::dict out;
  out["T_model_scan"] = Eigen::Matrix4d(scan.T_model_scan.matrix());
  std::vector<std::uint8_t> on_model(scan.on_model.begin(), scan.on_model.end());
  std::vector<std::int32_t> surface(scan.surface.begin(), scan.surface.end());
  py::array_t<double> uv({static_cast<py::ssize_t>(scan.uv.size()), py::ssize_t{2}});
  auto uv_rows = uv.mutable_unchecked<2>();
  for (std::size_t i = 0; i < scan.uv.size(); ++i) {
    uv_rows(static_cast<py::ssize_t>(i), 0) = scan.uv[i].x();
    uv_rows(static_cast<py::ssize_t>(i), 1) = scan.uv[i].y();
  }
  out["points"] = take_points(std::move(scan.points));
  out["on_model"] = take_vector(std::move(on_model)).attr("astype")("bool");
  out["surface"] = take_vector(std::move(surface));
  out["uv"] = uv;
  return out;
}

}  // namespace

void bind_point_io(py::module_& m) {
  m.def("read_point_cloud", &read_cloud, py::arg("path"));
  m.def("write_point_cloud", &write_cloud, py::arg("path"), py::arg("points"), py::arg("encoding"),
        py::arg("double_precision"));
  m.def("synth", &synth, py::arg("model"), py::arg("points"), py::arg("noise"), py::arg("pose"),
        py::arg("seed"), py::arg("outliers"), py::arg("view_fraction"), py::arg("view_direction"),
        py::arg("fixture"), py::arg("fixture_up"));
}

}  // namespace nurbsreg::python
