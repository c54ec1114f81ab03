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
    for (const BezierPatch& patch : decompose(model_.surfaces[s])) {
      patch_boxes_.push_back(bounding_box(patch));
      patch_spheres_.push_back(bounding_sphere(patch));
      patches_.push_back(prepare_patch(patch));
      patch_surface_.push_back(static_cast<int>(s));
      bounds_.extend(patch_boxes_.back());
    }
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

double PreparedModel::patch_lower_bound(std::size_t i, const Vec3& p) const {
  return std::max(patch_boxes_[i].squared_distance(p), sphere_lower_bound(patch_spheres_[i], p));
}

double PreparedModel::piece_lower_bound(std::size_t i, const Vec3& p) const {
  return std::max(piece_boxes_[i].squared_distance(p), sphere_lower_bound(piece_spheres_[i], p));
}

}  // namespace nurbsreg::engine
