#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/cancellation.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <iterator>
#include <limits>
#include <optional>
#include <stdexcept>

#include "model/patch_frame.hpp"
#include "model/prepared_model_internals.hpp"
#include "model/search_refinement.hpp"
#include "nurbsreg/engine/decompose.hpp"
#include "proofs/reach_bounds.hpp"
#include "trim/rectangle_face.hpp"

namespace nurbsreg::engine {
namespace {

// Does the 2-D rational Bézier curve (homogeneous (w u, w v, -, w)) meet the open box
// (u0, u1) x (v0, v1)? Conservative: true unless the control points' box of the curve, or of
// its halves down to kDepth levels, is proven clear of it (convex hull property).
bool meets_open_box(const BezierCurve& c, double u0, double u1, double v0, double v1, int depth) {
  constexpr int kDepth = 24;
  double lu = std::numeric_limits<double>::infinity(), hu = -lu, lv = lu, hv = -lu;
  for (int i = 0; i <= c.degree; ++i) {
    const double u = c.cw[i][0] / c.cw[i][3], v = c.cw[i][1] / c.cw[i][3];
    lu = std::min(lu, u);
    hu = std::max(hu, u);
    lv = std::min(lv, v);
    hv = std::max(hv, v);
  }
  if (hu <= u0 || lu >= u1 || hv <= v0 || lv >= v1) return false;
  if (depth >= kDepth) return true;
  BezierCurve left, right;
  c.split(0.5, left, right);
  return meets_open_box(left, u0, u1, v0, v1, depth + 1) ||
         meets_open_box(right, u0, u1, v0, v1, depth + 1);
}

// The boundary of a trimmed surface's region as TrimRegion builds it: every loop's Bézier
// pieces, and the straight pieces that close the gaps between consecutive ones (and between the
// last and the first); and the loops' tolerance (TrimRegion: 1e-13 x the parameter space's scale).
struct LoopBoundary {
  std::vector<BezierCurve> pieces;
  double band = 0.0;
};

LoopBoundary loop_boundary(const NurbsSurface& surface) {
  LoopBoundary b;
  const ParamInterval du = surface.domain_u(), dv = surface.domain_v();
  double scale = std::max(
      {std::abs(du.lo), std::abs(du.hi), std::abs(dv.lo), std::abs(dv.hi), du.width(), dv.width()});
  const auto segment = [](const Vec4& a, const Vec4& z) {
    BezierCurve c;
    c.degree = 1;
    c.cw[0] = Vec4(a[0] / a[3], a[1] / a[3], 0.0, 1.0);
    c.cw[1] = Vec4(z[0] / z[3], z[1] / z[3], 0.0, 1.0);
    return c;
  };
  for (const TrimLoop& loop : surface.trim_loops) {
    const std::size_t first = b.pieces.size();
    for (const TrimCurve& curve : loop.curves) {
      for (const Vec3& p : curve.uv.control_points)
        scale = std::max({scale, std::abs(p.x()), std::abs(p.y())});
      for (const BezierCurve& piece : decompose(curve.uv)) {
        if (b.pieces.size() > first) {
          b.pieces.push_back(segment(b.pieces.back().cw[b.pieces.back().degree], piece.cw[0]));
        }
        b.pieces.push_back(piece);
      }
    }
    if (b.pieces.size() > first) {
      b.pieces.push_back(
          segment(b.pieces.back().cw[b.pieces.back().degree], b.pieces[first].cw[0]));
    }
  }
  b.band = 1e-13 * scale;
  return b;
}

// A patch the region's grid calls `boundary` (TrimRegion::classify is conservative: a loop in a
// grid cell the patch only touches, or one along the patch's side, makes it so): when no loop
// piece enters the patch's box shrunk by the loops' tolerance, its interior is uniformly in or
// out of the region (up to that tolerance, within which a point is on a loop), and its centre
// says which.
RegionClass refine_patch_class(const LoopBoundary& loops, const TrimRegion& region,
                               const BezierPatch& bp) {
  const double e = loops.band;
  const double u0 = bp.param_u.lo + e, u1 = bp.param_u.hi - e;
  const double v0 = bp.param_v.lo + e, v1 = bp.param_v.hi - e;
  if (!(u1 - u0 > 2.0 * e && v1 - v0 > 2.0 * e)) return RegionClass::boundary;
  for (const BezierCurve& piece : loops.pieces) {
    if (meets_open_box(piece, u0, u1, v0, v1, 0)) return RegionClass::boundary;
  }
  return region.contains(0.5 * (bp.param_u.lo + bp.param_u.hi),
                         0.5 * (bp.param_v.lo + bp.param_v.hi))
             ? RegionClass::inside
             : RegionClass::outside;
}

}  // namespace

namespace {
std::atomic<std::uint32_t> next_serial{1};

// No knot strictly inside the domain repeats `degree` times or more (a B-spline is C^(p - m) at a
// knot of multiplicity m), in u and in v.
bool c1_across_spans(const NurbsSurface& s) {
  const auto c1 = [](const std::vector<double>& knots, int degree, int count) {
    const double lo = knots[static_cast<std::size_t>(degree)];
    const double hi = knots[static_cast<std::size_t>(count)];
    int run = 0;
    for (std::size_t k = 0; k < knots.size(); ++k) {
      run = k > 0 && knots[k] == knots[k - 1] ? run + 1 : 1;
      if (knots[k] > lo && knots[k] < hi && run >= degree) return false;
    }
    return true;
  };
  return c1(s.knots_u, s.degree_u, s.count_u) && c1(s.knots_v, s.degree_v, s.count_v);
}

}  // namespace

PreparedModel::PreparedModel(Model model)
    : model_(std::move(model)), reach_(std::make_shared<ReachState>()), serial_(next_serial++) {
  if (auto error = model_.validate()) throw std::invalid_argument(*error);
  // A face that is a rectangle of its surface's domain: that rectangle of the surface, untrimmed.
  rectangle_face_.assign(model_.surfaces.size(), 0);
  for (std::size_t s = 0; s < model_.surfaces.size(); ++s) {
    NurbsSurface& surface = model_.surfaces[s];
    if (const std::optional<UvRectangle> r = rectangle_of_face(surface)) {
      surface = restrict_domain(surface, r->u, r->v);
      rectangle_face_[s] = 1;
    }
  }
  // The trimmed regions first, in parallel (each is built from its own surface alone, so they are
  // the same for any number of threads); the error of the first invalid one, in surface order,
  // is the one reported, as in a serial build.
  std::vector<std::size_t> trimmed;
  for (std::size_t s = 0; s < model_.surfaces.size(); ++s) {
    surface_region_.push_back(-1);
    if (model_.surfaces[s].is_trimmed()) {
      surface_region_.back() = static_cast<int>(trimmed.size());
      trimmed.push_back(s);
    }
  }
  regions_.resize(trimmed.size());
  std::vector<std::exception_ptr> region_errors(trimmed.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, trimmed.size()),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t k = r.begin(); k != r.end(); ++k) {
                        try {
                          regions_[k] = TrimRegion(model_.surfaces[trimmed[k]]);
                        } catch (...) {
                          region_errors[k] = std::current_exception();
                        }
                      }
                    });
  nurbsreg::engine::stop_if_cancelled();
  for (const std::exception_ptr& e : region_errors) {
    if (e) std::rethrow_exception(e);
  }
  // The patches the search works on: each surface's Bézier patches, cut finer where they are far
  // from flat (refine_for_search: the same function of (u, v); model_ keeps the surface as
  // given). A task per surface, each from its own surface alone: the same patches for any number
  // of threads.
  std::vector<std::vector<BezierPatch>> surface_pieces(model_.surfaces.size());
  std::vector<Aabb> given_boxes(model_.surfaces.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, model_.surfaces.size()),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t s = r.begin(); s != r.end(); ++s) {
                        const SpanPieces cut = search_pieces(model_.surfaces[s]);
                        surface_pieces[s] = decompose(refine_for_search(model_.surfaces[s], cut));
                        given_boxes[s] = cut.control_box;
                      }
                    });
  nurbsreg::engine::stop_if_cancelled();
  for (const Aabb& box : given_boxes)
    bounds_.extend(box);
  for (std::size_t s = 0; s < model_.surfaces.size(); ++s) {
    const NurbsSurface& surface = model_.surfaces[s];
    SurfacePatches layout;
    layout.first = patches_.size();
    const std::vector<BezierPatch> pieces = std::move(surface_pieces[s]);
    surface_certifiable_.push_back(0);
    for (const BezierPatch& patch : pieces) {
      patches_.push_back(prepare_patch(patch));
      patch_surface_.push_back(static_cast<int>(s));
      patch_class_.push_back(RegionClass::inside);
      surface_certifiable_.back() = 1;
      any_certifiable_ = true;
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
    for (std::size_t k = 0; k < pieces.size(); ++k) {
      patch_span_.push_back(
          {static_cast<int>(k) / layout.spans_v, static_cast<int>(k) % layout.spans_v});
    }
    surface_c1_.push_back(c1_across_spans(surface) ? 1 : 0);
    surface_domain_.push_back({surface.domain_u(), surface.domain_v(), surface.reversed});
    surface_patches_.push_back(std::move(layout));
  }
  // Classify the trimmed surfaces' patches (regions_ is complete: pointers into it are stable):
  // the grid first, then, where it cannot tell, the loops themselves (refine_patch_class).
  LoopBoundary loops;
  int loops_of = -1;  // the surface `loops` belongs to (patches come surface by surface)
  for (std::size_t i = 0; i < patches_.size(); ++i) {
    const TrimRegion* region = surface_region(patch_surface_[i]);
    if (region == nullptr) continue;
    const BezierPatch& bp = patches_[i].patch;
    patch_class_[i] = region->classify(bp.param_u.lo, bp.param_u.hi, bp.param_v.lo, bp.param_v.hi);
    if (patch_class_[i] == RegionClass::boundary) {
      if (loops_of != patch_surface_[i]) {
        loops = loop_boundary(model_.surfaces[static_cast<std::size_t>(patch_surface_[i])]);
        loops_of = patch_surface_[i];
      }
      patch_class_[i] = refine_patch_class(loops, *region, bp);
    }
  }
  // Hierarchy items: the patches that are not trimmed away, then the trim-edge pieces.
  for (std::size_t i = 0; i < patches_.size(); ++i) {
    if (patch_class_[i] == RegionClass::outside) continue;
    item_patch_.push_back(static_cast<std::uint32_t>(i));
    // The prepared patch already holds its bounds.
    item_boxes_.push_back(patches_[i].box);
    item_spheres_.push_back(patches_[i].sphere);
    const BezierPatch& bp = patches_[i].patch;
    OrientedBox ob;
    oriented_axes(bp, ob.axis);
    extents_along(bp, ob.axis, ob.lo, ob.hi);
    // Rounding in the projections (relative 1e-15 of |x|): widen so the box still holds every
    // control point's true projection.
    for (int k = 0; k < 3; ++k) {
      const double slack = 1e-14 * (std::abs(ob.lo[k]) + std::abs(ob.hi[k]) +
                                    (patches_[i].box.hi - patches_[i].box.lo).norm());
      ob.lo[k] -= slack;
      ob.hi[k] += slack;
    }
    item_oriented_.push_back(ob);
  }
  // The trim-edge pieces, a task per trimmed surface (each from its own surface alone), then
  // appended in surface order: the same items for any number of threads.
  struct SurfaceEdges {
    std::vector<PreparedCurvePiece> pieces;
    std::vector<EdgePiece> info;
    std::vector<Aabb> boxes;
    std::vector<BoundingSphere> spheres;
  };
  std::vector<SurfaceEdges> edges(trimmed.size());
  std::vector<std::exception_ptr> edge_errors(trimmed.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, trimmed.size()),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t k = r.begin(); k != r.end(); ++k) {
                        try {
                          const std::size_t s = trimmed[k];
                          SurfaceEdges& e = edges[k];
                          for (const TrimEdge& edge : trim_edges(model_.surfaces[s])) {
                            for (const BezierCurve& piece : decompose(edge.edge)) {
                              e.pieces.push_back(prepare_curve_piece(piece));
                              e.info.push_back({static_cast<int>(s), edge.loop, edge.curve});
                              e.boxes.push_back(bounding_box(piece));
                              e.spheres.push_back(bounding_sphere(piece));
                            }
                          }
                        } catch (...) {
                          edge_errors[k] = std::current_exception();
                        }
                      }
                    });
  nurbsreg::engine::stop_if_cancelled();
  for (const std::exception_ptr& e : edge_errors) {
    if (e) std::rethrow_exception(e);
  }
  for (SurfaceEdges& e : edges) {
    edge_pieces_.insert(edge_pieces_.end(), std::make_move_iterator(e.pieces.begin()),
                        std::make_move_iterator(e.pieces.end()));
    edge_piece_info_.insert(edge_piece_info_.end(), e.info.begin(), e.info.end());
    item_spheres_.insert(item_spheres_.end(), e.spheres.begin(), e.spheres.end());
    for (const Aabb& box : e.boxes) {
      item_boxes_.push_back(box);
      bounds_.extend(box);
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
  patch_bvh_ = std::make_shared<const Bvh>(item_boxes_, 2);
  // The seed grid: cells of 1/32 of the model's longest side, or finer where that would make
  // fewer than 8192 cells in all: a long blade gets 8 x 8 x 138, not 2 x 2 x 32, so that a seed's
  // distance, which bounds the walk's first steps, is about the point's own, not the blade's
  // width (a finer grid for every part cost more in cache misses than it saved). Each cell's point
  // is the sample nearest to its centre of the patch a greedy descent from the centre reaches, on
  // a trimmed face only a sample inside the face (seed_from_grid). Outside the model's box the
  // nearest cell is used.
  if (!patch_bvh_->empty() && !item_patch_.empty() && !bounds_.empty()) {
    constexpr int kCellsAlongLongest = 32;
    constexpr double kLeastCells = 8192.0;
    constexpr int kMostCellsAlongAnAxis = 512;
    const Vec3 extent = bounds_.hi - bounds_.lo;
    const double longest = std::max(extent.maxCoeff(), 1e-300);
    // A flat or thin model's box counts as at least 1/32 of its longest side in every direction.
    const double least = longest / kCellsAlongLongest;
    const double volume =
        std::max(extent.x(), least) * std::max(extent.y(), least) * std::max(extent.z(), least);
    const double cell = std::min(longest / kCellsAlongLongest, std::cbrt(volume / kLeastCells));
    seed_lo_ = bounds_.lo;
    seed_inv_cell_ = 1.0 / cell;
    for (int a = 0; a < 3; ++a)
      seed_dims_[a] =
          std::clamp(static_cast<int>(std::ceil(extent[a] / cell)), 1, kMostCellsAlongAnAxis);
    seed_cells_.resize(static_cast<std::size_t>(seed_dims_[0]) * seed_dims_[1] * seed_dims_[2]);
    // Cell (x, y, z): the sample nearest its centre.
    const auto seed_cell = [&](int x, int y, int z) {
      const Vec3 centre = seed_lo_ + cell * Vec3(x + 0.5, y + 0.5, z + 0.5);
      const std::int64_t item = patch_bvh_->greedy_primitive(centre);
      if (item < 0 || static_cast<std::size_t>(item) >= item_patch_.size()) return;
      const std::uint32_t k = item_patch_[static_cast<std::size_t>(item)];
      if (patch_class_[k] == RegionClass::outside) return;
      // A patch the trim loops cross: only its samples inside the face.
      const TrimRegion* region = patch_region(k);
      const BezierPatch& bp = patches_[k].patch;
      SeedCell& c =
          seed_cells_[(static_cast<std::size_t>(z) * seed_dims_[1] + y) * seed_dims_[0] + x];
      double nearest = std::numeric_limits<double>::infinity();
      for (int a = 0; a < kSeedSamples; ++a) {
        for (int b = 0; b < kSeedSamples; ++b) {
          const double s = double(a) / (kSeedSamples - 1), t = double(b) / (kSeedSamples - 1);
          if (region != nullptr &&
              !region->contains(bp.param_u.to_parent(s), bp.param_v.to_parent(t)))
            continue;
          const Vec3 point = bp.evaluate(s, t);
          const double d = (point - centre).squaredNorm();
          if (d < nearest) {
            nearest = d;
            c = {static_cast<std::int64_t>(k), s, t, point};
          }
        }
      }
    };
    // Every cell on its own: the same grid for any number of threads.
    tbb::parallel_for(0, seed_dims_[2], [&](int z) {
      for (int y = 0; y < seed_dims_[1]; ++y) {
        for (int x = 0; x < seed_dims_[0]; ++x)
          seed_cell(x, y, z);
      }
    });
  }
  piece_bvh_ = std::make_shared<const Bvh>(piece_boxes_, 2);
}

PreparedModel::PreparedModel(const PreparedModel&) = default;
PreparedModel::PreparedModel(PreparedModel&&) noexcept = default;
PreparedModel& PreparedModel::operator=(const PreparedModel&) = default;
PreparedModel& PreparedModel::operator=(PreparedModel&&) noexcept = default;
PreparedModel::~PreparedModel() = default;

int PreparedModel::reach_cells_per_side() const {
  return reach_->k;
}

void PreparedModel::prepare_reach_bounds() const {
  std::call_once(reach_->once, [this] {
    ReachTable table = build_reach_table(*this);
    reach_->first = std::move(table.first);
    reach_->cells = std::move(table.cells);
    reach_->k = table.cells_per_side;
    reach_->ready.store(true, std::memory_order_release);
  });
}

std::int64_t PreparedModel::locate_patch(int surface, double u, double v) const {
  const SurfacePatches& layout = surface_patches_[static_cast<std::size_t>(surface)];
  if (layout.spans_u == 0 || layout.spans_v == 0) return -1;
  // The last span whose lower bound is <= the parameter (the first span below all of them): the
  // number of lower bounds after the first that are <= x. Counted without branches up to 64
  // spans (a binary search's branches mispredict on every call of a warm frame's scattered
  // hints), by binary search beyond.
  auto span = [](const std::vector<double>& breaks, double x) {
    const std::size_t n = breaks.size();
    if (n <= 64) {
      int count = 0;
      for (std::size_t k = 1; k < n; ++k)
        count += breaks[k] <= x ? 1 : 0;
      return count;
    }
    const auto it = std::upper_bound(breaks.begin() + 1, breaks.end(), x);
    return static_cast<int>(it - breaks.begin()) - 1;
  };
  const int a = span(layout.breaks_u, u), b = span(layout.breaks_v, v);
  return static_cast<std::int64_t>(layout.first) + static_cast<std::int64_t>(a) * layout.spans_v +
         b;
}

bool PreparedModel::seed_from_grid(const Vec3& p, double limit_sq, SurfaceHit& best, int& surface,
                                   std::int64_t& patch) const {
  if (seed_cells_.empty()) return false;
  int cell[3];
  for (int a = 0; a < 3; ++a) {
    const double x = (p[a] - seed_lo_[a]) * seed_inv_cell_;
    // NaN-safe: the caller passes finite points only, but a clamp of NaN must not index.
    cell[a] = x > 0.0 ? static_cast<int>(std::min(x, double(seed_dims_[a] - 1))) : 0;
  }
  const SeedCell& c =
      seed_cells_[(static_cast<std::size_t>(cell[2]) * seed_dims_[1] + cell[1]) * seed_dims_[0] +
                  cell[0]];
  if (c.patch < 0) return false;
  const double d = (c.point - p).squaredNorm();
  if (!(d < limit_sq)) return false;
  const BezierPatch& bp = patches_[static_cast<std::size_t>(c.patch)].patch;
  best.s = c.s;
  best.t = c.t;
  best.u = bp.param_u.to_parent(c.s);
  best.v = bp.param_v.to_parent(c.t);
  best.distance_sq = d;
  best.foot = c.point;
  best.normal = Vec3::Zero();
  surface = patch_surface_[static_cast<std::size_t>(c.patch)];
  patch = c.patch;
  return true;
}

Vec2 PreparedModel::edge_uv(std::size_t i, double t) const {
  const EdgePiece& e = edge_piece_info_[i];
  const NurbsCurve& uv = model_.surfaces[static_cast<std::size_t>(e.surface)]
                             .trim_loops[static_cast<std::size_t>(e.loop)]
                             .curves[static_cast<std::size_t>(e.curve)]
                             .uv;
  const Vec3 x = uv.evaluate(t);
  return {x.x(), x.y()};
}

double PreparedModel::piece_lower_bound(std::size_t i, const Vec3& p) const {
  return std::max(piece_boxes_[i].squared_distance(p), piece_spheres_[i].squared_distance(p));
}

}  // namespace nurbsreg::engine
