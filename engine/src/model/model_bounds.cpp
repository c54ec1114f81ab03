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
  bool rational = false;  // weights not all equal
  double slack = 0.0;     // rounding margin of the control points' coordinates
};

struct Node {
  double upper = 0.0;
  std::uint32_t item = 0;
  // Local box (curves: [a0, a1]); a side of zero width makes an iso segment, two a point.
  double a0 = 0.0, a1 = 1.0, b0 = 0.0, b1 = 1.0;
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
      it.rational = model.patch(i).rational;
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
        if (evaluate(n, axis, sign)) heap.push(n);
      }
      std::size_t nodes = 0;
      double side = -std::numeric_limits<double>::infinity();
      while (!heap.empty()) {
        const Node top = heap.top();
        const double best = sign > 0 ? witnessed_.hi[axis] : -witnessed_.lo[axis];
        if (top.upper - best <= tolerance || top.frozen) {
          side = top.upper;
          break;
        }
        if (nodes >= options_.max_nodes_per_direction) {
          result.budget_spent = true;
          side = top.upper;
          break;
        }
        heap.pop();
        // Split across the longer side (a side of zero width is an iso segment: along the other).
        const bool along_a = items_[top.item].curve != nullptr || top.b1 == top.b0 ||
                             (top.a1 > top.a0 && top.split_a);
        const double width = along_a ? top.a1 - top.a0 : top.b1 - top.b0;
        if (!(width > kMinWidth)) {
          side = top.upper;  // cannot be refined: its bound is final
          break;
        }
        Node child[2] = {top, top};
        if (along_a) {
          child[0].a1 = child[1].a0 = 0.5 * (top.a0 + top.a1);
        } else {
          child[0].b1 = child[1].b0 = 0.5 * (top.b0 + top.b1);
        }
        for (Node& c : child) {
          ++nodes;
          if (evaluate(c, axis, sign)) heap.push(c);
        }
      }
      result.nodes += nodes;
      // Every node left lies below `side`; every node dropped holds no geometry above it.
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
  struct LoopBox {
    LoopPiece piece;
    double u0, u1, v0, v1;  // its control points' box
  };

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

  const std::vector<LoopBox>& loops(int surface) {
    std::optional<std::vector<LoopBox>>& l = loops_[static_cast<std::size_t>(surface)];
    if (!l) {
      l.emplace();
      for (const LoopPiece& p :
           loop_pieces(model_.model().surfaces[static_cast<std::size_t>(surface)])) {
        LoopBox b{p, INFINITY, -INFINITY, INFINITY, -INFINITY};
        for (int i = 0; i <= p.degree; ++i) {
          const double u = p.cw[i].x() / p.cw[i].z(), v = p.cw[i].y() / p.cw[i].z();
          b.u0 = std::min(b.u0, u);
          b.u1 = std::max(b.u1, u);
          b.v0 = std::min(b.v0, v);
          b.v1 = std::max(b.v1, v);
        }
        l->push_back(b);
      }
    }
    return *l;
  }

  // The class of a sub-box (possibly of zero width: an iso segment or a point) of a boundary
  // patch: the region's grid first, then (where the grid cannot tell) the exact test against the
  // loop pieces: a box no loop piece meets is uniformly in or out, and its centre says which.
  RegionClass classify(const Item& it, const Node& n) {
    const BezierPatch& bp = *it.patch;
    const double u0 = bp.param_u.to_parent(n.a0), u1 = bp.param_u.to_parent(n.a1);
    const double v0 = bp.param_v.to_parent(n.b0), v1 = bp.param_v.to_parent(n.b1);
    const RegionClass grid = it.region->classify(u0, u1, v0, v1);
    if (grid != RegionClass::boundary) return grid;
    const double scale = std::max({std::abs(u0), std::abs(u1), std::abs(v0), std::abs(v1),
                                   bp.param_u.width(), bp.param_v.width()});
    const double tiny = 1e-13 * scale;
    const double lu = u0 - tiny, hu = u1 + tiny, lv = v0 - tiny, hv = v1 + tiny;
    for (const LoopBox& b : loops(it.surface)) {
      if (b.u1 < lu || b.u0 > hu || b.v1 < lv || b.v0 > hv) continue;
      if (piece_meets(b.piece.cw.data(), b.piece.degree, lu, hu, lv, hv, tiny, 0))
        return RegionClass::boundary;
    }
    return it.region->contains(0.5 * (u0 + u1), 0.5 * (v0 + v1)) ? RegionClass::inside
                                                                 : RegionClass::outside;
  }

  // Strictly monotone coordinate along a direction of a (sub-)net, by the sign of d: +1
  // increasing, -1 decreasing, 0 neither (or not provably). x(i, j) is the coordinate of control
  // point (i, j) of an (n + 1) x (m + 1) net along the direction; a polynomial net's s-curves are
  // then the column averages, so positive differences suffice; a rational net's are convex
  // combinations with varying weights, so each column must lie above the whole previous one
  // (variation diminishing property of positive-weight Bézier curves: strictly monotone control
  // coordinates make a strictly monotone curve).
  template <class X>
  static int monotone(const X& x, int n, int m, bool rational, double margin) {
    bool up = true, down = true;
    for (int i = 0; i < n && (up || down); ++i) {
      if (rational) {
        double lo0 = INFINITY, hi0 = -INFINITY, lo1 = INFINITY, hi1 = -INFINITY;
        for (int j = 0; j <= m; ++j) {
          lo0 = std::min(lo0, x(i, j));
          hi0 = std::max(hi0, x(i, j));
          lo1 = std::min(lo1, x(i + 1, j));
          hi1 = std::max(hi1, x(i + 1, j));
        }
        up = up && lo1 - hi0 > margin;
        down = down && lo0 - hi1 > margin;
      } else {
        for (int j = 0; j <= m; ++j) {
          const double d = x(i + 1, j) - x(i, j);
          up = up && d > margin;
          down = down && d < -margin;
        }
      }
    }
    return up ? 1 : (down ? -1 : 0);
  }

  // Prepares node n for direction (axis, sign): its class (dropped when outside: returns false),
  // n.upper (the sub-net's extreme, widened for rounding), its model points (corners in the
  // face; a curve's ends) into witnessed_, and its split direction. A node whose coordinate is
  // strictly monotone along s (or t, or a curve's t) is replaced by its side (end) where the
  // coordinate is largest: the face's largest value in the box lies there or on a trim edge
  // (a point of the face's interior that is not on that side can move along s within the box
  // and the face and grow), and the trim edges are items of their own. A node reduced to a
  // point is final: frozen, its value attained (or dropped when the point is not in the face).
  bool evaluate(Node& n, int axis, double sign) {
    const Item& it = items_[n.item];
    std::array<Vec4, kMaxNet> net;
    if (it.curve != nullptr) {
      const BezierCurve& c = *it.curve;
      const int deg = c.degree;
      for (int k = 0; k <= deg; ++k)
        net[k] = c.cw[k];
      restrict_curve(net.data(), 1, deg, n.a0, n.a1);
      witness(net[0]);
      witness(net[deg]);
      const auto x = [&](int i, int) { return sign * net[i][axis] / net[i][3]; };
      const int mono = deg > 0 ? monotone(x, deg, 0, false, 2.0 * it.slack) : 0;
      if (mono != 0) {
        n.upper = x(mono > 0 ? deg : 0, 0) + it.slack;
        n.frozen = true;
        return true;
      }
      double upper = -INFINITY;
      for (int k = 0; k <= deg; ++k)
        upper = std::max(upper, x(k, 0));
      n.upper = upper + it.slack;
      return true;
    }
    if (it.region != nullptr && n.cls == RegionClass::boundary) {
      n.cls = classify(it, n);
      if (n.cls == RegionClass::outside) return false;
    }
    const BezierPatch& bp = *it.patch;
    const int p = bp.degree_u, q = bp.degree_v, stride = q + 1;
    for (std::size_t k = 0; k < bp.cw.size(); ++k)
      net[k] = bp.cw[k];
    for (int j = 0; j <= q; ++j)
      restrict_curve(net.data() + j, stride, p, n.a0, n.a1);
    for (int i = 0; i <= p; ++i)
      restrict_curve(net.data() + i * stride, 1, q, n.b0, n.b1);
    // The corners are surface points; in the face when the box is inside, or when the region
    // contains their (u, v).
    const int corner[4][2] = {{0, 0}, {p, 0}, {0, q}, {p, q}};
    bool corner_in[4];
    for (int k = 0; k < 4; ++k) {
      bool in = n.cls == RegionClass::inside;
      if (!in && it.region != nullptr) {
        const double u = bp.param_u.to_parent(corner[k][0] == 0 ? n.a0 : n.a1);
        const double v = bp.param_v.to_parent(corner[k][1] == 0 ? n.b0 : n.b1);
        in = it.region->contains(u, v);
      }
      corner_in[k] = in;
      if (in) witness(net[corner[k][0] * stride + corner[k][1]]);
    }
    const auto x = [&](int i, int j) {
      const Vec4& c = net[i * stride + j];
      return sign * c[axis] / c[3];
    };
    if (n.a0 == n.a1 && n.b0 == n.b1) {  // a point: final
      if (!corner_in[0]) return false;
      n.upper = x(0, 0) + it.slack;
      n.frozen = true;
      return true;
    }
    const double margin = 2.0 * it.slack;
    if (n.a1 > n.a0) {
      const int mono = monotone(x, p, q, it.rational, margin);
      if (mono != 0) {
        if (mono > 0)
          n.a0 = n.a1;
        else
          n.a1 = n.a0;
        return evaluate(n, axis, sign);
      }
    }
    if (n.b1 > n.b0) {
      const auto xt = [&](int j, int i) { return x(i, j); };
      const int mono = monotone(xt, q, p, it.rational, margin);
      if (mono != 0) {
        if (mono > 0)
          n.b0 = n.b1;
        else
          n.b1 = n.b0;
        return evaluate(n, axis, sign);
      }
    }
    double upper = -INFINITY;
    for (int k = 0; k < (p + 1) * stride; ++k)
      upper = std::max(upper, x(k / stride, k % stride));
    n.upper = upper + it.slack;
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
    return true;
  }

  void witness(const Vec4& h) { witnessed_.extend(Vec3(h.head<3>() / h[3])); }

  const PreparedModel& model_;
  ModelBoundsOptions options_;
  std::vector<Item> items_;
  std::vector<std::optional<std::vector<LoopBox>>> loops_;  // per surface, built when needed
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
