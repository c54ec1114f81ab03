#pragma once
// The immutable, prepared form of a model: every surface decomposed into rational Bézier
// patches with their cached squared-distance coefficients and bounds, every curve into pieces,
// and a bounding volume hierarchy over all patches (and one over all pieces).
//
// Trimmed surfaces (NurbsSurface::trim_loops): a face that is a rectangle of its domain becomes
// that rectangle of the surface, untrimmed (rectangle_face); every other gets a TrimRegion, and
// each of its patches
// is classified on its parameter box: patches outside the region are left out of the hierarchy
// (never visited), patches inside it are projected as untrimmed ones, patches that may straddle a
// loop run the trimmed clipping (project_onto_patch with the region). The face's 3-D trim edges
// (trim_edges) are decomposed into Bézier pieces and put into the SAME hierarchy as the patches,
// so one best-first walk handles both: the closest point of a trimmed face is the best of the
// region's interior points and its edges' points (issue 7).
//
// Built once (allocates); afterwards const and thread-safe: any number of threads may project
// against one PreparedModel at the same time.

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/curve_projection.hpp"
#include "nurbsreg/engine/model.hpp"
#include "nurbsreg/engine/model_bounds.hpp"
#include "nurbsreg/engine/surface_projection.hpp"
#include "nurbsreg/engine/trim_region.hpp"

namespace nurbsreg::engine {

class Bvh;  // the bounding volume hierarchy (engine-internal: src/model/bvh.hpp)

class PreparedModel {
 public:
  // Validates the model (throws std::invalid_argument with Model::validate()'s message; also
  // when a trimmed surface's region or edges cannot be built: TrimRegion, trim_edges).
  explicit PreparedModel(Model model);
  // Copies share the geometry (it is immutable) and the reach bounds.
  PreparedModel(const PreparedModel&);
  PreparedModel(PreparedModel&&) noexcept;
  PreparedModel& operator=(const PreparedModel&);
  PreparedModel& operator=(PreparedModel&&) noexcept;
  ~PreparedModel();

  const Model& model() const { return model_; }

  // Every patch of every surface, trimmed away or not (locate_patch's layout).
  std::size_t patch_count() const { return patches_.size(); }
  const PreparedPatch& patch(std::size_t i) const { return patches_[i]; }
  // Index of the surface patch i belongs to.
  int patch_surface(std::size_t i) const { return patch_surface_[i]; }
  // The region to clip patch i against: null when the patch is untrimmed or proven inside its
  // face's region; the face's region when the patch may straddle a loop.
  const TrimRegion* patch_region(std::size_t i) const {
    return patch_class_[i] == RegionClass::boundary ? surface_region(patch_surface_[i]) : nullptr;
  }
  // inside for an untrimmed surface's patches.
  RegionClass patch_class(std::size_t i) const { return patch_class_[i]; }
  // The trimmed region of surface s, or null for an untrimmed surface.
  const TrimRegion* surface_region(int s) const {
    const int r = surface_region_[static_cast<std::size_t>(s)];
    return r < 0 ? nullptr : &regions_[static_cast<std::size_t>(r)];
  }

  // Surface s is a face whose trim loop cut out a rectangle of its domain: model() holds that
  // rectangle of the surface, untrimmed (the same (u, v); trim/rectangle_face.hpp). Its border is
  // the face's trim edge (ProjectionResults::on_trim_edge).
  bool rectangle_face(int s) const { return rectangle_face_[static_cast<std::size_t>(s)] != 0; }

  // Surface s's parameter domain (NurbsSurface::domain_u / domain_v, read from its knots) and
  // orientation: kept side by side, since every answer and hint reads them (the surfaces
  // themselves lie far apart in memory, each a miss).
  struct SurfaceDomain {
    ParamInterval u, v;
    bool reversed = false;  // NurbsSurface::reversed: the outer side is -(S_u x S_v)
  };
  const SurfaceDomain& surface_domain(int s) const {
    return surface_domain_[static_cast<std::size_t>(s)];
  }

  // Can a WarmCertificate be made for a foot on surface s: has it a polynomial patch
  // (certify_patch proves convexity on polynomial patches only; on a trimmed face only for a box
  // the region proves inside it)? And on any surface of the model? A projector certifies only
  // where it can (ProjectionOptions::certify).
  bool surface_certifiable(int s) const {
    return surface_certifiable_[static_cast<std::size_t>(s)] != 0;
  }
  bool any_certifiable() const { return any_certifiable_; }

  // The Bézier patches the search uses for surface s: its own, cut finer where they are far from
  // flat (the same function of (u, v); see model/search_refinement.hpp).
  std::size_t surface_patch_count(int s) const {
    const SurfacePatches& layout = surface_patches_[static_cast<std::size_t>(s)];
    return static_cast<std::size_t>(layout.spans_u) * static_cast<std::size_t>(layout.spans_v);
  }
  // Where patch i sits in its surface's grid of Bézier patches: u span a, v span b.
  struct SpanCell {
    int a = 0, b = 0;
  };
  SpanCell patch_span(std::size_t i) const { return patch_span_[i]; }
  // The patch of surface s at span cell (a, b); -1 outside the surface's grid.
  std::int64_t patch_at(int surface, int a, int b) const {
    const SurfacePatches& layout = surface_patches_[static_cast<std::size_t>(surface)];
    if (a < 0 || b < 0 || a >= layout.spans_u || b >= layout.spans_v) return -1;
    return static_cast<std::int64_t>(layout.first) + static_cast<std::int64_t>(a) * layout.spans_v +
           b;
  }
  // Surface s is C1 in (u, v) across every patch edge (no interior knot of multiplicity >= its
  // degree): F_q = |S - q|^2 is then C1 across them, so F_q strictly convex on every patch's part
  // of a parameter box makes it strictly convex on the box (a WarmCertificate may span patches).
  bool surface_c1(int s) const { return surface_c1_[static_cast<std::size_t>(s)] != 0; }

  // Reach bounds (proofs/reach_bounds.cpp): for a foot f on an untrimmed polynomial surface, a
  // lower bound of how far a point may lie from f along a direction of f's normal cone and still
  // have f as its closest point on the whole model, so that such a query is answered without any
  // search (ProjectionOptions::reach_bounds). One ReachCell per cell of a k x k grid of each such
  // patch's local (s, t) square; the cell type and reach_cell() are engine-internal
  // (src/proofs/reach_bounds.hpp).
  // Built only on request (prepare_reach_bounds: about 0.2 ms per cell on 2 cores, ~2.3 s for a
  // 49-patch model at 16 x 16 cells a patch): they pay where frames come with bare (surface, u,
  // v) hints (tracking without certificates: ~0.3 us of wall time saved per point on 2 cores on
  // the 49-patch benchmark panel, so after about seven million points), not in a one-off cold
  // frame nor in ICP, whose certificates already skip the search (the default alignment took
  // 0.86 s without them and 1.75 s with 0.8 s bounds built during its run).
  static constexpr int kReachSectors = 8;
  static constexpr std::uint32_t kNoReach = 0xffffffffu;  // a patch without cells
  struct ReachCell;
  // Builds the bounds once (thread-safe; later calls return at once).
  void prepare_reach_bounds() const;
  // Cells per patch side: 16, 8, 4, 2 or 1 (fewer on models of many patches: construction
  // time).
  int reach_cells_per_side() const;
  // Patch i's cell holding local (s, t) in [0, 1]^2; null when the patch has no reach bounds or
  // they are not built. Inline in src/proofs/reach_bounds.hpp (the projection's hot path).
  const ReachCell* reach_cell(std::size_t i, double s, double t) const;

  // The surfaces' hierarchy. Its primitives ("items") are the patches that are not trimmed away,
  // k < hierarchy_patch_items(), with item_patch(k) their patch index, then the trim-edge pieces,
  // edge piece k - hierarchy_patch_items(). For a model without trimmed surfaces the items are
  // exactly the patches, item_patch(k) == k.
  const Bvh& patch_hierarchy() const { return *patch_bvh_; }
  std::size_t hierarchy_patch_items() const { return item_patch_.size(); }
  std::uint32_t item_patch(std::uint32_t k) const { return item_patch_[k]; }
  // Cold start: an upper bound on p's squared distance to the surfaces before any clipping, so
  // that the hierarchy walk prunes from its first step. A surface point stored for p's cell of a
  // coarse grid over the model (computed at construction: of the patch that
  // patch_hierarchy().greedy_primitive reaches from the cell's centre, if it is a patch that is
  // not trimmed (class inside), the sample of a small (s, t) grid nearest to the centre), when
  // its squared distance is below limit_sq. Then writes the corner to best
  // (distance_sq, foot, u, v, local s and t; normal zero: the caller evaluates it if the corner
  // stays the answer), its surface and patch, and returns true; otherwise changes nothing.
  bool seed_from_grid(const Vec3& p, double limit_sq, SurfaceHit& best, int& surface,
                      std::int64_t& patch) const;

  // Squared-distance lower bound from p to item k, to be combined with the item's box distance
  // (the hierarchy walk does, Bvh::nearest): a patch's oriented box (OrientedBox), an edge
  // piece's bounding sphere. Inline (src/model/prepared_model_internals.hpp): the walk calls it
  // for every leaf it reaches, and inlined it runs in the walk's own (possibly AVX2) code.
  double item_lower_bound(std::uint32_t k, const Vec3& p) const;
  // The same combined with the item's own axis-aligned box: the bound the walk orders item k by.
  double item_bound(std::uint32_t k, const Vec3& p) const;

  // Trim-edge pieces: Bézier pieces of the faces' 3-D boundary edges (trim_edges).
  struct EdgePiece {
    int surface = -1;
    int loop = -1, curve = -1;  // the trim curve: trim_loops[loop].curves[curve]
  };
  std::size_t edge_piece_count() const { return edge_pieces_.size(); }
  const PreparedCurvePiece& edge_piece(std::size_t i) const { return edge_pieces_[i]; }
  const EdgePiece& edge_piece_info(std::size_t i) const { return edge_piece_info_[i]; }
  // (u, v) of the edge point with curve parameter t: the trim curve's uv(t) (same parameter).
  Vec2 edge_uv(std::size_t i, double t) const;
  // The patch of surface `surface` whose parameter box holds (u, v) (clamped to the domain), by
  // binary search over the surface's patch breakpoints; -1 if the surface has no patches.
  std::int64_t locate_patch(int surface, double u, double v) const;

  std::size_t piece_count() const { return pieces_.size(); }
  const PreparedCurvePiece& piece(std::size_t i) const { return pieces_[i]; }
  int piece_curve(std::size_t i) const { return piece_curve_[i]; }
  const Bvh& piece_hierarchy() const { return *piece_bvh_; }
  double piece_lower_bound(std::size_t i, const Vec3& p) const;

  // Box around every control point of the model (contains the whole model).
  const Aabb& bounds() const { return bounds_; }
  // The proven box of the model's actual geometry: trimmed faces as trimmed, their edges, the
  // curves (model_bounds.hpp). The size of the model for users: `info`, scan-size checks,
  // size-derived defaults. Computed on first use (thread-safe, milliseconds), shared by copies.
  const ModelBounds& geometry_bounds() const;
  // A number no other PreparedModel of this process has (copies share it, as they share the
  // geometry): warm certificates carry it, so one made for another model is never trusted.
  std::uint32_t serial() const { return serial_; }

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
  std::vector<SpanCell> patch_span_;           // per patch
  std::vector<std::uint8_t> surface_c1_;       // per surface (surface_c1)
  std::vector<std::uint8_t> rectangle_face_;   // per surface (rectangle_face)
  std::vector<SurfaceDomain> surface_domain_;  // per surface (surface_domain)
  std::vector<RegionClass> patch_class_;
  std::vector<TrimRegion> regions_;
  std::vector<int> surface_region_;                // per surface: index into regions_, -1 untrimmed
  std::vector<std::uint8_t> surface_certifiable_;  // per surface (surface_certifiable)
  bool any_certifiable_ = false;
  std::vector<std::uint32_t> item_patch_;
  // Shared by copies (they share the geometry); written once, then read-only
  // (src/proofs/reach_bounds.hpp).
  struct ReachState;
  std::shared_ptr<ReachState> reach_;
  std::vector<Aabb> item_boxes_;  // per hierarchy item (patches, then edge pieces)
  std::vector<BoundingSphere> item_spheres_;
  // A box in the patch's own frame per patch item, and the cold-start seed grid: cells of side
  // 1 / seed_inv_cell_ from seed_lo_, x fastest (src/model/prepared_model_internals.hpp).
  struct OrientedBox;
  std::vector<OrientedBox> item_oriented_;  // per patch item (k < hierarchy_patch_items())
  static constexpr int kSeedSamples = 5;
  struct SeedCell;
  Vec3 seed_lo_ = Vec3::Zero();
  double seed_inv_cell_ = 0.0;
  int seed_dims_[3] = {0, 0, 0};
  std::vector<SeedCell> seed_cells_;
  std::vector<PreparedCurvePiece> edge_pieces_;
  std::vector<EdgePiece> edge_piece_info_;
  std::shared_ptr<const Bvh> patch_bvh_;  // never null after construction
  std::vector<PreparedCurvePiece> pieces_;
  std::vector<int> piece_curve_;
  std::vector<Aabb> piece_boxes_;
  std::vector<BoundingSphere> piece_spheres_;
  std::shared_ptr<const Bvh> piece_bvh_;
  Aabb bounds_;
  struct GeometryBounds {
    std::once_flag once;
    ModelBounds bounds;
  };
  std::shared_ptr<GeometryBounds> geometry_bounds_ = std::make_shared<GeometryBounds>();
  std::uint32_t serial_ = 0;
};

}  // namespace nurbsreg::engine
