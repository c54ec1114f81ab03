// compute_model_bounds: a proven, tight box of the trimmed faces, trim edges and curves (see
// model_bounds.hpp for the method and its guarantee).

#include "nurbsreg/engine/model_bounds.hpp"

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <queue>

#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/prepared_model.hpp"

namespace nurbsreg::engine {
namespace {

constexpr int kMaxNet = (kMaxDegree + 1) * (kMaxDegree + 1);
// Sub-boxes narrower than this (local parameter) are not split further.
constexpr double kMinWidth = 1e-12;
constexpr int kMaxLoopDepth = 40;  // halvings of a loop piece in the exact box test

// A loop piece of a trimmed face in (u, v), homogeneous (w u, w v, w).
struct LoopPiece {
  int degree = 1;
  std::array<Vec3, kMaxDegree + 1> cw{};
};

// What the branch and bound runs over: a patch of a face (with the face's region, null when the
// patch is proven inside) or a curve piece (trim edge or model curve: every point is geometry).
struct Item {
  const BezierPatch* patch = nullptr;
  const BezierCurve* curve = nullptr;
  const TrimRegion* region = nullptr;
  int surface = -1;
  RegionClass cls = RegionClass::inside;
  double slack = 0.0;  // rounding margin of the control points' coordinates
};

struct Node {
  double upper = 0.0;
  std::uint32_t item = 0;
  double a0 = 0.0, a1 = 1.0, b0 = 0.0, b1 = 1.0;  // local box (curves: [a0, a1])
  RegionClass cls = RegionClass::inside;
  bool split_a = true;  // patches: split along s (else t)
  bool frozen = false;  // its upper bound is attained (a monotone curve's end point)
  bool operator<(const Node& o) const { return upper < o.upper; }
};

// Restricts the Bézier curve a[k * stride], k = 0..n, to [t0, t1] in place (two de Casteljau
// splits from the given points: the error does not grow with the depth of the search).
void restrict_curve(Vec4* a, int stride, int n, double t0, double t1) {
  Vec4 w[kMaxDegree + 1], part[kMaxDegree + 1];
  for (int k = 0; k <= n; ++k)
    w[k] = a[k * stride];
  if (t1 < 1.0) {  // the part over [0, t1]
    part[0] = w[0];
    for (int r = 1; r <= n; ++r) {
      for (int i = 0; i <= n - r; ++i)
        w[i] = (1.0 - t1) * w[i] + t1 * w[i + 1];
      part[r] = w[0];
    }
    for (int k = 0; k <= n; ++k)
      w[k] = part[k];
  }
  if (t0 > 0.0) {  // then its part over [t0 / t1, 1]
    const double t = t0 / t1;
    part[n] = w[n];
    for (int r = 1; r <= n; ++r) {
      for (int i = 0; i <= n - r; ++i)
        w[i] = (1.0 - t) * w[i] + t * w[i + 1];
      part[n - r] = w[n - r];
    }
    for (int k = 0; k <= n; ++k)
      w[k] = part[k];
  }
  for (int k = 0; k <= n; ++k)
    a[k * stride] = w[k];
}

void halve2(const Vec3* a, int n, Vec3* left, Vec3* right) {
  Vec3 w[kMaxDegree + 1];
  for (int i = 0; i <= n; ++i)
    w[i] = a[i];
  left[0] = w[0];
  right[n] = w[n];
  for (int r = 1; r <= n; ++r) {
    for (int i = 0; i <= n - r; ++i)
      w[i] = 0.5 * (w[i] + w[i + 1]);
    left[r] = w[0];
    right[n - r] = w[n - r];
  }
}

// May the loop piece a[0..n] meet the closed box? False is a proof (its control points' box,
// convex hull property, misses the box); true may be a false alarm after kMaxLoopDepth halvings.
bool piece_meets(const Vec3* a, int n, double u0, double u1, double v0, double v1, double tiny,
                 int depth) {
  double lu = std::numeric_limits<double>::infinity(), hu = -lu, lv = lu, hv = -lu;
  for (int i = 0; i <= n; ++i) {
    const double u = a[i].x() / a[i].z(), v = a[i].y() / a[i].z();
    lu = std::min(lu, u);
    hu = std::max(hu, u);
    lv = std::min(lv, v);
    hv = std::max(hv, v);
  }
  if (hu < u0 || lu > u1 || hv < v0 || lv > v1) return false;
  if (n == 1 || depth >= kMaxLoopDepth || std::max(hu - lu, hv - lv) < tiny) {
    if (n > 1) return true;
    // A straight segment whose box meets the box: it misses when every corner of the box is on
    // the same side of its line.
    const Vec2 p(a[0].x() / a[0].z(), a[0].y() / a[0].z());
    const Vec2 q(a[1].x() / a[1].z(), a[1].y() / a[1].z());
    const Vec2 d = q - p;
    const double corners[4][2] = {{u0, v0}, {u1, v0}, {u0, v1}, {u1, v1}};
    bool pos = false, neg = false;
    const double margin = tiny * d.norm();
    for (const auto& c : corners) {
      const double side = d.x() * (c[1] - p.y()) - d.y() * (c[0] - p.x());
      pos = pos || side > -margin;
      neg = neg || side < margin;
    }
    return pos && neg;
  }
  Vec3 left[kMaxDegree + 1], right[kMaxDegree + 1];
  halve2(a, n, left, right);
  return piece_meets(left, n, u0, u1, v0, v1, tiny, depth + 1) ||
         piece_meets(right, n, u0, u1, v0, v1, tiny, depth + 1);
}

// The trim loops of a surface as TrimRegion sees them: the uv curves' Bézier pieces, with gaps
// between consecutive pieces (and the closing one) bridged by straight pieces.
std::vector<LoopPiece> loop_pieces(const NurbsSurface& surface) {
  std::vector<LoopPiece> out;
  const auto segment = [](const Vec3& a, const Vec3& b) {
    LoopPiece s;
    s.degree = 1;
    s.cw[0] = Vec3(a.x() / a.z(), a.y() / a.z(), 1.0);
    s.cw[1] = Vec3(b.x() / b.z(), b.y() / b.z(), 1.0);
    return s;
  };
  const auto same = [](const Vec3& a, const Vec3& b) {
    return a.x() / a.z() == b.x() / b.z() && a.y() / a.z() == b.y() / b.z();
  };
  for (const TrimLoop& loop : surface.trim_loops) {
    const std::size_t first = out.size();
    for (const TrimCurve& curve : loop.curves) {
      for (const BezierCurve& bez : decompose(curve.uv)) {
        LoopPiece p;
        p.degree = bez.degree;
        for (int i = 0; i <= bez.degree; ++i)
          p.cw[i] = Vec3(bez.cw[i][0], bez.cw[i][1], bez.cw[i][3]);
        if (out.size() > first) {
          const LoopPiece& prev = out.back();
          if (!same(prev.cw[prev.degree], p.cw[0]))
            out.push_back(segment(prev.cw[prev.degree], p.cw[0]));
        }
        out.push_back(p);
      }
    }
    if (out.size() > first) {
      const LoopPiece& last = out.back();
      if (!same(last.cw[last.degree], out[first].cw[0]))
        out.push_back(segment(last.cw[last.degree], out[first].cw[0]));
    }
  }
  return out;
}

class BoundsSearch {
 public:
  BoundsSearch(const PreparedModel& model, const ModelBoundsOptions& options, int only_surface)
      : model_(model), options_(options), loops_(model.model().surfaces.size()) {
    for (std::size_t i = 0; i < model.patch_count(); ++i) {
      const int s = model.patch_surface(i);
      if (only_surface >= 0 && s != only_surface) continue;
      const RegionClass cls = model.patch_class(i);
      if (cls == RegionClass::outside) continue;
      Item it;
      it.patch = &model.patch(i).patch;
      it.surface = s;
      it.cls = cls;
      it.region = cls == RegionClass::boundary ? model.surface_region(s) : nullptr;
      it.slack = rounding_slack(it.patch->cw.data(), static_cast<int>(it.patch->cw.size()),
                                it.patch->degree_u + it.patch->degree_v);
      items_.push_back(it);
    }
    for (std::size_t i = 0; i < model.edge_piece_count(); ++i) {
      if (only_surface >= 0 && model.edge_piece_info(i).surface != only_surface) continue;
      add_curve(model.edge_piece(i).piece);
    }
    if (only_surface < 0) {
      for (std::size_t i = 0; i < model.piece_count(); ++i)
        add_curve(model.piece(i).piece);
    }
  }

  ModelBounds run() {
    ModelBounds result;
    // Witnesses of the items themselves (their corners and end points) set the tolerance.
    for (std::uint32_t k = 0; k < items_.size(); ++k) {
      Node n;
      n.item = k;
      n.cls = items_[k].cls;
      evaluate(n, 0, 1.0);
    }
    const double tolerance = options_.relative_tolerance * std::max(witnessed_.diagonal(), 1e-300);
    double sides[6];
    double max_slack = 0.0;
    for (const Item& it : items_)
      max_slack = std::max(max_slack, it.slack);
    for (int d = 0; d < 6; ++d) {
      const int axis = d / 2;
      const double sign = d % 2 == 0 ? 1.0 : -1.0;
      std::priority_queue<Node> heap;
      for (std::uint32_t k = 0; k < items_.size(); ++k) {
        Node n;
        n.item = k;
        n.cls = items_[k].cls;
        evaluate(n, axis, sign);
        heap.push(n);
      }
      std::size_t nodes = 0;
      double side = -std::numeric_limits<double>::infinity();
      while (!heap.empty()) {
        const Node top = heap.top();
        const double best = sign > 0 ? witnessed_.hi[axis] : -witnessed_.lo[axis];
        if (top.upper - best <= tolerance || top.frozen ||
            nodes >= options_.max_nodes_per_direction) {
          if (nodes >= options_.max_nodes_per_direction && top.upper - best > tolerance)
            result.budget_spent = true;
          side = top.upper;
          break;
        }
        heap.pop();
        const Item& it = items_[top.item];
        Node child[2] = {top, top};
        if (it.curve != nullptr || top.split_a) {
          if (!(top.a1 - top.a0 > kMinWidth)) {
            side = top.upper;  // cannot be refined: its bound is final
            break;
          }
          const double mid = 0.5 * (top.a0 + top.a1);
          child[0].a1 = mid;
          child[1].a0 = mid;
        } else {
          if (!(top.b1 - top.b0 > kMinWidth)) {
            side = top.upper;
            break;
          }
          const double mid = 0.5 * (top.b0 + top.b1);
          child[0].b1 = mid;
          child[1].b0 = mid;
        }
        for (Node& c : child) {
          if (it.patch != nullptr && c.cls == RegionClass::boundary) {
            c.cls = classify(it, c);
            if (c.cls == RegionClass::outside) continue;
          }
          ++nodes;
          evaluate(c, axis, sign);
          heap.push(c);
        }
      }
      result.nodes += nodes;
      // Every node left lies below `side`; every node dropped holds no geometry.
      sides[d] = side;
    }
    if (!witnessed_.empty() && std::isfinite(sides[0])) {
      result.box.lo = Vec3(-sides[1], -sides[3], -sides[5]);
      result.box.hi = Vec3(sides[0], sides[2], sides[4]);
      // A side within the rounding margin of a model point is that point's coordinate: exact up
      // to rounding (the sphere's box is [-1, 1]^3, not 1 + 1e-15).
      for (int a = 0; a < 3; ++a) {
        if (result.box.hi[a] - witnessed_.hi[a] <= 2.0 * max_slack)
          result.box.hi[a] = witnessed_.hi[a];
        if (witnessed_.lo[a] - result.box.lo[a] <= 2.0 * max_slack)
          result.box.lo[a] = witnessed_.lo[a];
      }
      // The box always holds what was witnessed (the tolerance test may stop on a node whose
      // bound rounds below a witness).
      result.box.extend(witnessed_);
      result.witnessed = witnessed_;
      result.excess = std::max((result.box.hi - witnessed_.hi).maxCoeff(),
                               (witnessed_.lo - result.box.lo).maxCoeff());
      result.exact = result.excess == 0.0;
    }
    return result;
  }

 private:
  // Margin for the rounding of restricted control points and their division by w: a few ulps of
  // the largest coordinate per de Casteljau step, times the spread of the weights (a rational
  // point is a ratio of two rounded sums).
  static double rounding_slack(const Vec4* cw, int count, int degrees) {
    double m = 0.0, wmin = std::numeric_limits<double>::infinity(), wmax = 0.0;
    for (int k = 0; k < count; ++k) {
      m = std::max(m, (cw[k].head<3>() / cw[k][3]).cwiseAbs().maxCoeff());
      wmin = std::min(wmin, cw[k][3]);
      wmax = std::max(wmax, cw[k][3]);
    }
    return 16.0 * DBL_EPSILON * (degrees + 2) * (wmax / wmin) * m;
  }

  void add_curve(const BezierCurve& c) {
    Item it;
    it.curve = &c;
    it.slack = rounding_slack(c.cw.data(), c.degree + 1, c.degree);
    items_.push_back(it);
  }

  // The class of a boundary sub-patch: the region's grid first, then (where the grid cannot
  // tell) the exact test against the loop pieces: a box no loop piece meets is uniformly in or
  // out, and its centre says which.
  RegionClass classify(const Item& it, const Node& n) {
    const BezierPatch& bp = *it.patch;
    const double u0 = bp.param_u.to_parent(n.a0), u1 = bp.param_u.to_parent(n.a1);
    const double v0 = bp.param_v.to_parent(n.b0), v1 = bp.param_v.to_parent(n.b1);
    const RegionClass grid = it.region->classify(u0, u1, v0, v1);
    if (grid != RegionClass::boundary) return grid;
    std::optional<std::vector<LoopPiece>>& loops = loops_[static_cast<std::size_t>(it.surface)];
    if (!loops) loops = loop_pieces(model_.model().surfaces[static_cast<std::size_t>(it.surface)]);
    const double scale =
        std::max({std::abs(u0), std::abs(u1), std::abs(v0), std::abs(v1), u1 - u0, v1 - v0});
    const double tiny = 1e-13 * scale;
    for (const LoopPiece& p : *loops) {
      if (piece_meets(p.cw.data(), p.degree, u0 - tiny, u1 + tiny, v0 - tiny, v1 + tiny, tiny, 0))
        return RegionClass::boundary;
    }
    return it.region->contains(0.5 * (u0 + u1), 0.5 * (v0 + v1)) ? RegionClass::inside
                                                                 : RegionClass::outside;
  }

  // Fills n.upper (direction sign * e_axis), records the node's model points (corners in the
  // face; a curve's ends) in witnessed_, chooses the split direction, freezes monotone curves.
  void evaluate(Node& n, int axis, double sign) {
    const Item& it = items_[n.item];
    std::array<Vec4, kMaxNet> net;
    if (it.curve != nullptr) {
      const BezierCurve& c = *it.curve;
      const int deg = c.degree;
      for (int k = 0; k <= deg; ++k)
        net[k] = c.cw[k];
      restrict_curve(net.data(), 1, deg, n.a0, n.a1);
      double upper = -std::numeric_limits<double>::infinity();
      bool up = true, down = true;
      double prev = 0.0;
      for (int k = 0; k <= deg; ++k) {
        const double x = sign * net[k][axis] / net[k][3];
        upper = std::max(upper, x);
        if (k > 0) {
          up = up && x > prev;
          down = down && x < prev;
        }
        prev = x;
      }
      witness(net[0]);
      witness(net[deg]);
      // Strictly monotone control points: so is the curve (variation diminishing property), so
      // its largest value is at an end point, which is a model point.
      if (deg > 0 && (up || down)) {
        const Vec4& end = up ? net[deg] : net[0];
        upper = sign * end[axis] / end[3];
        n.frozen = true;
      }
      n.upper = upper + it.slack;
      return;
    }
    const BezierPatch& bp = *it.patch;
    const int p = bp.degree_u, q = bp.degree_v, stride = q + 1;
    for (std::size_t k = 0; k < bp.cw.size(); ++k)
      net[k] = bp.cw[k];
    for (int j = 0; j <= q; ++j)
      restrict_curve(net.data() + j, stride, p, n.a0, n.a1);
    for (int i = 0; i <= p; ++i)
      restrict_curve(net.data() + i * stride, 1, q, n.b0, n.b1);
    double upper = -std::numeric_limits<double>::infinity();
    for (int k = 0; k < (p + 1) * stride; ++k)
      upper = std::max(upper, sign * net[k][axis] / net[k][3]);
    n.upper = upper + it.slack;
    // The corners are surface points; in the face when the box is inside, or when the region
    // contains their (u, v).
    const int corner[4][2] = {{0, 0}, {p, 0}, {0, q}, {p, q}};
    for (const auto& c : corner) {
      bool in = n.cls == RegionClass::inside;
      if (!in && it.region != nullptr) {
        const double u = bp.param_u.to_parent(c[0] == 0 ? n.a0 : n.a1);
        const double v = bp.param_v.to_parent(c[1] == 0 ? n.b0 : n.b1);
        in = it.region->contains(u, v);
      }
      if (in) witness(net[c[0] * stride + c[1]]);
    }
    // Split across the direction in which the sub-net is longer in space.
    double along_s = 0.0, along_t = 0.0;
    for (int j = 0; j <= q; ++j)
      along_s = std::max(along_s, (net[p * stride + j].head<3>() / net[p * stride + j][3] -
                                   net[j].head<3>() / net[j][3])
                                      .squaredNorm());
    for (int i = 0; i <= p; ++i)
      along_t = std::max(along_t, (net[i * stride + q].head<3>() / net[i * stride + q][3] -
                                   net[i * stride].head<3>() / net[i * stride][3])
                                      .squaredNorm());
    n.split_a = along_s >= along_t;
  }

  void witness(const Vec4& h) { witnessed_.extend(Vec3(h.head<3>() / h[3])); }

  const PreparedModel& model_;
  ModelBoundsOptions options_;
  std::vector<Item> items_;
  std::vector<std::optional<std::vector<LoopPiece>>> loops_;  // per surface, built when needed
  Aabb witnessed_;
};

}  // namespace

ModelBounds compute_model_bounds(const PreparedModel& model, const ModelBoundsOptions& options) {
  return BoundsSearch(model, options, -1).run();
}

ModelBounds compute_surface_bounds(const PreparedModel& model, int surface,
                                   const ModelBoundsOptions& options) {
  return BoundsSearch(model, options, surface).run();
}

}  // namespace nurbsreg::engine

namespace nurbsreg::engine {

const ModelBounds& PreparedModel::geometry_bounds() const {
  std::call_once(geometry_bounds_->once,
                 [this] { geometry_bounds_->bounds = compute_model_bounds(*this); });
  return geometry_bounds_->bounds;
}

}  // namespace nurbsreg::engine
