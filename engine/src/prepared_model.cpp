#include "nurbsreg/engine/prepared_model.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "nurbsreg/engine/decompose.hpp"

namespace nurbsreg::engine {
namespace {

double sphere_lower_bound(const BoundingSphere& s, const Vec3& p) {
  const double d = std::max(0.0, (p - s.center).norm() - s.radius);
  return d * d;
}

}  // namespace

PreparedModel::PreparedModel(Model model) : model_(std::move(model)) {
  if (auto error = model_.validate()) throw std::invalid_argument(*error);
  for (std::size_t s = 0; s < model_.surfaces.size(); ++s) {
    SurfacePatches layout;
    layout.first = patches_.size();
    const std::vector<BezierPatch> pieces = decompose(model_.surfaces[s]);
    for (const BezierPatch& patch : pieces) {
      patch_boxes_.push_back(bounding_box(patch));
      patch_spheres_.push_back(bounding_sphere(patch));
      patches_.push_back(prepare_patch(patch));
      patch_surface_.push_back(static_cast<int>(s));
      bounds_.extend(patch_boxes_.back());
    }
    // Recover the span grid from the patches' parameter boxes and check the layout: the warm
    // start's patch lookup relies on it (a mismatch is an internal error, not bad input).
    for (const BezierPatch& patch : pieces) {
      if (patch.param_u.lo != pieces.front().param_u.lo) break;
      layout.breaks_v.push_back(patch.param_v.lo);
    }
    layout.spans_v = static_cast<int>(layout.breaks_v.size());
    if (layout.spans_v > 0) {
      layout.spans_u = static_cast<int>(pieces.size()) / layout.spans_v;
      for (int a = 0; a < layout.spans_u; ++a)
        layout.breaks_u.push_back(pieces[static_cast<std::size_t>(a) * layout.spans_v].param_u.lo);
    }
    bool consistent = static_cast<std::size_t>(layout.spans_u) * layout.spans_v == pieces.size();
    for (std::size_t k = 0; consistent && k < pieces.size(); ++k) {
      const int a = static_cast<int>(k) / std::max(layout.spans_v, 1);
      const int b = static_cast<int>(k) % std::max(layout.spans_v, 1);
      consistent =
          pieces[k].param_u.lo == layout.breaks_u[a] && pieces[k].param_v.lo == layout.breaks_v[b];
    }
    if (!consistent) {
      throw std::logic_error("PreparedModel: surface '" + model_.surfaces[s].name +
                             "': Bézier patches are not in span order");
    }
    surface_patches_.push_back(std::move(layout));
  }
  for (std::size_t c = 0; c < model_.curves.size(); ++c) {
    for (const BezierCurve& piece : decompose(model_.curves[c])) {
      piece_boxes_.push_back(bounding_box(piece));
      piece_spheres_.push_back(bounding_sphere(piece));
      pieces_.push_back(prepare_curve_piece(piece));
      piece_curve_.push_back(static_cast<int>(c));
      bounds_.extend(piece_boxes_.back());
    }
  }
  patch_bvh_ = Bvh(patch_boxes_, 2);
  piece_bvh_ = Bvh(piece_boxes_, 2);
}

std::int64_t PreparedModel::locate_patch(int surface, double u, double v) const {
  const SurfacePatches& layout = surface_patches_[static_cast<std::size_t>(surface)];
  if (layout.spans_u == 0 || layout.spans_v == 0) return -1;
  // The last span whose lower bound is <= the parameter (the first span below all of them).
  auto span = [](const std::vector<double>& breaks, double x) {
    const auto it = std::upper_bound(breaks.begin() + 1, breaks.end(), x);
    return static_cast<int>(it - breaks.begin()) - 1;
  };
  const int a = span(layout.breaks_u, u), b = span(layout.breaks_v, v);
  return static_cast<std::int64_t>(layout.first) + static_cast<std::int64_t>(a) * layout.spans_v +
         b;
}

double PreparedModel::patch_lower_bound(std::size_t i, const Vec3& p) const {
  return std::max(patch_boxes_[i].squared_distance(p), sphere_lower_bound(patch_spheres_[i], p));
}

double PreparedModel::piece_lower_bound(std::size_t i, const Vec3& p) const {
  return std::max(piece_boxes_[i].squared_distance(p), sphere_lower_bound(piece_spheres_[i], p));
}

}  // namespace nurbsreg::engine
