#pragma once
// The immutable, prepared form of a model: every surface decomposed into rational Bézier
// patches with their cached squared-distance coefficients and bounds, every curve into pieces,
// and a bounding volume hierarchy over all patches (and one over all pieces).
//
// Built once (allocates); afterwards const and thread-safe: any number of threads may project
// against one PreparedModel at the same time.

#include <cstdint>
#include <vector>

#include "nurbsreg/engine/bvh.hpp"
#include "nurbsreg/engine/curve_projection.hpp"
#include "nurbsreg/engine/model.hpp"
#include "nurbsreg/engine/surface_projection.hpp"

namespace nurbsreg::engine {

class PreparedModel {
 public:
  // Validates the model (throws std::invalid_argument with Model::validate()'s message).
  explicit PreparedModel(Model model);

  const Model& model() const { return model_; }

  std::size_t patch_count() const { return patches_.size(); }
  const PreparedPatch& patch(std::size_t i) const { return patches_[i]; }
  // Index of the surface patch i belongs to.
  int patch_surface(std::size_t i) const { return patch_surface_[i]; }
  const Bvh& patch_hierarchy() const { return patch_bvh_; }
  // The patch of surface `surface` whose parameter box holds (u, v) (clamped to the domain), by
  // binary search over the surface's patch breakpoints; -1 if the surface has no patches.
  std::int64_t locate_patch(int surface, double u, double v) const;
  // Squared-distance lower bound from p to patch i (box and sphere).
  double patch_lower_bound(std::size_t i, const Vec3& p) const;

  std::size_t piece_count() const { return pieces_.size(); }
  const PreparedCurvePiece& piece(std::size_t i) const { return pieces_[i]; }
  int piece_curve(std::size_t i) const { return piece_curve_[i]; }
  const Bvh& piece_hierarchy() const { return piece_bvh_; }
  double piece_lower_bound(std::size_t i, const Vec3& p) const;

  // Box around every control point of the model (contains the whole model).
  const Aabb& bounds() const { return bounds_; }

 private:
  Model model_;
  std::vector<PreparedPatch> patches_;
  std::vector<int> patch_surface_;
  // Per surface: its patches are [first, first + spans_u * spans_v), laid out [a * spans_v + b]
  // for u span a and v span b (decompose's order, checked at construction), with the spans'
  // lower parameter bounds in breaks_u / breaks_v.
  struct SurfacePatches {
    std::size_t first = 0;
    int spans_u = 0, spans_v = 0;
    std::vector<double> breaks_u, breaks_v;
  };
  std::vector<SurfacePatches> surface_patches_;
  std::vector<Aabb> patch_boxes_;
  std::vector<BoundingSphere> patch_spheres_;
  Bvh patch_bvh_;
  std::vector<PreparedCurvePiece> pieces_;
  std::vector<int> piece_curve_;
  std::vector<Aabb> piece_boxes_;
  std::vector<BoundingSphere> piece_spheres_;
  Bvh piece_bvh_;
  Aabb bounds_;
};

}  // namespace nurbsreg::engine
