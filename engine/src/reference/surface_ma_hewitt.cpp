// Ma & Hewitt's control polygon method for surfaces (seed paper 000): Algorithm 1
// (Is_Valid_Polygon), 2 (Is_Valid_CP_Net), 3 (Point_Nearest_Bezier_Curve), 4
// (Point_Nearest_Bezier_Patch), 5 (curve candidates, used on the boundary curves of §8), 6
// (Nearest_Candidate_Points_Surface) and §9 (Newton on the flat-enough sub-patch).
//
// Kept as a comparison strategy. Its Theorem 1 (the test behind Algorithms 3 and 4) does not hold
// in 3-D (seed 001 ref. [1]), so it can discard the patch holding the closest point; the tests show
// such a case. Deviations from the pseudocode, each because the pseudocode as printed would not
// terminate: the split direction alternates (Algorithm 6 passes Dir unchanged to both halves) and
// the recursion limit also applies to nets that never become valid.

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>

#include "bernstein/de_casteljau.hpp"
#include "nurbsreg/engine/surface_projection.hpp"

namespace nurbsreg::engine {
namespace {

constexpr int kNetSide = kMaxDegree + 1;
constexpr int kMaxRecursion = 20;   // total binary splits (10 per direction)
constexpr double kFlatness = 1e-3;  // control net within this fraction of its size of a plane

// A sub-patch's Cartesian control net and its box in the prepared patch's local [0, 1]^2.
struct Net {
  int du = 0, dv = 0;
  double s0 = 0, s1 = 1, t0 = 0, t1 = 1;
  std::array<Vec4, kNetSide * kNetSide> cw;
  Vec3 point(int i, int j) const {
    const Vec4& c = cw[i * (dv + 1) + j];
    return c.head<3>() / c[3];
  }
};

void split(const Net& in, bool along_u, Net& low, Net& high) {
  low = in;
  high = in;
  const int stride = in.dv + 1;
  if (along_u) {
    for (int j = 0; j <= in.dv; ++j)
      halve(in.cw.data() + j, stride, in.du, low.cw.data() + j, high.cw.data() + j);
    low.s1 = high.s0 = 0.5 * (in.s0 + in.s1);
  } else {
    for (int i = 0; i <= in.du; ++i)
      halve(in.cw.data() + i * stride, 1, in.dv, low.cw.data() + i * stride,
            high.cw.data() + i * stride);
    low.t1 = high.t0 = 0.5 * (in.t0 + in.t1);
  }
}

Vec3 project_on_line(const Vec3& x, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  if (len2 == 0.0) return a;
  return a + ab * ((x - a).dot(ab) / len2);
}

// Algorithm 1: every interior vertex bends to the "convex" side (dot product test, §4.1).
bool is_valid_polygon(const Vec3* pts, int n) {
  for (int i = 1; i < n; ++i) {
    const Vec3 v1 = project_on_line(pts[i], pts[i - 1], pts[i + 1]);
    const Vec3& end = i < n / 2.0 ? pts[n] : pts[0];
    const Vec3 v2 = project_on_line(end, pts[i - 1], pts[i + 1]);
    if ((pts[i] - v1).dot(end - v2) > 0) return false;
  }
  return true;
}

// Algorithm 3 (Theorem 1): FALSE when the nearest point must be an end point.
bool point_nearest_curve(const Vec3* pts, int n, const Vec3& p) {
  const double r1 = (p - pts[0]).dot(pts[1] - pts[0]);
  const double r2 = (pts[n] - p).dot(pts[n] - pts[n - 1]);
  const double r3 = (pts[0] - pts[n]).dot(p - pts[n]);
  const double r4 = (pts[0] - pts[n]).dot(p - pts[0]);
  return !((r1 < 0 || r2 < 0) && r3 * r4 > 0);
}

template <typename Fn>
bool all_polygons(const Net& net, bool along_u, Fn fn) {
  Vec3 pts[kNetSide] = {};
  const int lines = along_u ? net.dv : net.du;
  const int n = along_u ? net.du : net.dv;
  for (int l = 0; l <= lines; ++l) {
    for (int k = 0; k <= n; ++k)
      pts[k] = along_u ? net.point(k, l) : net.point(l, k);
    if (!fn(pts, n)) return false;
  }
  return true;
}

template <typename Fn>
bool any_polygon(const Net& net, bool along_u, Fn fn) {
  return !all_polygons(net, along_u, [&](const Vec3* pts, int n) { return !fn(pts, n); });
}

// Algorithm 2.
bool is_valid_net(const Net& net) {
  return all_polygons(net, true, is_valid_polygon) && all_polygons(net, false, is_valid_polygon);
}

// Algorithm 4: TRUE when the nearest point may be inside the patch.
bool point_nearest_patch(const Net& net, const Vec3& p) {
  auto test = [&](const Vec3* pts, int n) { return n < 1 || point_nearest_curve(pts, n, p); };
  return any_polygon(net, true, test) && any_polygon(net, false, test);
}

// "Flat enough": every control point within kFlatness * size of the plane through the corners'
// centroid spanned by the diagonals.
bool flat_enough(const Net& net) {
  const Vec3 a = net.point(0, 0), b = net.point(net.du, 0), c = net.point(0, net.dv),
             d = net.point(net.du, net.dv);
  const Vec3 centre = 0.25 * (a + b + c + d);
  Vec3 normal = (d - a).cross(c - b);
  Aabb box;
  for (int i = 0; i <= net.du; ++i) {
    for (int j = 0; j <= net.dv; ++j)
      box.extend(net.point(i, j));
  }
  const double size = box.diagonal();
  if (normal.norm() <= 1e-300) return size == 0.0;
  normal.normalize();
  for (int i = 0; i <= net.du; ++i) {
    for (int j = 0; j <= net.dv; ++j) {
      if (std::abs((net.point(i, j) - centre).dot(normal)) > kFlatness * size) return false;
    }
  }
  return true;
}

struct MaHewitt {
  const PreparedPatch& pp;
  const Vec3& p;
  SurfaceProjectionStats& st;
  double best_value = std::numeric_limits<double>::infinity();
  double best_s = 0, best_t = 0;
  Vec3 best_foot = Vec3::Zero();

  // The candidate of a flat sub-patch: p projected onto the corner parallelogram gives the start,
  // Newton on the sub-patch refines it (§7, §9).
  void candidate(const Net& net) {
    const Vec3 a = net.point(0, 0), b = net.point(net.du, 0), c = net.point(0, net.dv),
               d = net.point(net.du, net.dv);
    const Vec3 eu = 0.5 * ((b + d) - (a + c)), ev = 0.5 * ((c + d) - (a + b));
    const Vec3 x = p - 0.25 * (a + b + c + d);
    const double m11 = eu.dot(eu), m12 = eu.dot(ev), m22 = ev.dot(ev);
    const double det = m11 * m22 - m12 * m12;
    double x1 = 0.5, x2 = 0.5;
    if (det > 1e-14 * (m11 * m22) && det > 0) {
      x1 = 0.5 + (m22 * eu.dot(x) - m12 * ev.dot(x)) / det;
      x2 = 0.5 + (m11 * ev.dot(x) - m12 * eu.dot(x)) / det;
    }
    double s = net.s0 + std::clamp(x1, 0.0, 1.0) * (net.s1 - net.s0);
    double t = net.t0 + std::clamp(x2, 0.0, 1.0) * (net.t1 - net.t0);
    Vec3 foot;
    const double value =
        newton_on_patch(pp.patch, p, net.s0, net.s1, net.t0, net.t1, s, t, foot, &st);
    if (value < best_value) {
      best_value = value;
      best_s = s;
      best_t = t;
      best_foot = foot;
    }
  }

  // Algorithm 6.
  void recurse(const Net& net, bool dir_u, bool valid, int depth) {
    if (valid) {
      if (!point_nearest_patch(net, p)) return;
      if (flat_enough(net) || depth >= kMaxRecursion) {
        if (depth >= kMaxRecursion) ++st.depth_limit_hits;
        candidate(net);
        return;
      }
    } else if (is_valid_net(net)) {
      valid = true;
    } else if (depth >= kMaxRecursion) {
      ++st.depth_limit_hits;
      candidate(net);
      return;
    }
    ++st.subdivisions;
    Net low, high;
    split(net, dir_u, low, high);
    recurse(low, !dir_u, valid, depth + 1);
    recurse(high, !dir_u, valid, depth + 1);
  }
};

}  // namespace

bool project_onto_patch_ma_hewitt(const PreparedPatch& pp, const Vec3& p, SurfaceHit& best,
                                  SurfaceProjectionStats* stats) {
  if (!p.allFinite()) return false;
  SurfaceProjectionStats local;
  ++local.patches_visited;
  MaHewitt mh{pp, p, local};
  Net net;
  net.du = pp.patch.degree_u;
  net.dv = pp.patch.degree_v;
  std::copy(pp.patch.cw.begin(), pp.patch.cw.end(), net.cw.begin());
  mh.recurse(net, true, false, 0);
  bool improved = false;
  if (mh.best_value < best.distance_sq) {
    best.u = pp.patch.param_u.to_parent(mh.best_s);
    best.v = pp.patch.param_v.to_parent(mh.best_t);
    best.distance_sq = mh.best_value;
    best.foot = mh.best_foot;
    improved = true;
  }
  if (stats) stats->add(local);
  return improved;
}

// §8: the closest point is also sought on the surface's boundary curves (four for an open
// surface, two when closed in one direction, boundary points where an edge collapses), each by
// Algorithm 5 (curve candidates) on the Bézier pieces of the boundary and Newton on the piece.
void SurfaceProjector::ma_hewitt_boundaries(const Vec3& p, SurfaceHit& best,
                                            SurfaceProjectionStats* stats) const {
  SurfaceProjectionStats local;
  for (int a = 0; a < spans_u_; ++a) {
    for (int b = 0; b < spans_v_; ++b) {
      const PreparedPatch& pp = patches_[a * spans_v_ + b];
      const BezierPatch& bp = pp.patch;
      // Edges of this patch on the surface boundary: 0: s = 0, 1: s = 1, 2: t = 0, 3: t = 1.
      const bool on_edge[4] = {a == 0 && !closed_u_, a == spans_u_ - 1 && !closed_u_,
                               b == 0 && !closed_v_, b == spans_v_ - 1 && !closed_v_};
      for (int edge = 0; edge < 4; ++edge) {
        if (!on_edge[edge]) continue;
        const bool along_t = edge <= 1;
        const double fixed = (edge == 0 || edge == 2) ? 0.0 : 1.0;
        BezierCurve curve;
        curve.degree = along_t ? bp.degree_v : bp.degree_u;
        for (int k = 0; k <= curve.degree; ++k) {
          curve.cw[k] = along_t ? bp.at(fixed == 0.0 ? 0 : bp.degree_u, k)
                                : bp.at(k, fixed == 0.0 ? 0 : bp.degree_v);
        }
        curve.param = {0.0, 1.0};
        // Algorithm 5 on the boundary piece (recursive with an explicit depth).
        struct Frame {
          BezierCurve c;
          bool valid;
          int depth;
        };
        auto newton_on = [&](double lo, double hi) {
          double s = along_t ? fixed : 0.5 * (lo + hi);
          double t = along_t ? 0.5 * (lo + hi) : fixed;
          Vec3 foot;
          const double value =
              newton_on_patch(bp, p, along_t ? fixed : lo, along_t ? fixed : hi,
                              along_t ? lo : fixed, along_t ? hi : fixed, s, t, foot, &local);
          if (value < best.distance_sq) {
            best.distance_sq = value;
            best.u = bp.param_u.to_parent(s);
            best.v = bp.param_v.to_parent(t);
            best.foot = foot;
          }
        };
        // The ends of a boundary curve are points of it too: projecting onto the curve (§8)
        // includes them, though Algorithm 5 drops pieces whose nearest point is an end.
        newton_on(0.0, 0.0);
        newton_on(1.0, 1.0);
        Frame stack[2 * kMaxRecursion + 4];
        int top = 0;
        stack[top++] = {curve, false, 0};
        while (top > 0) {
          Frame f = stack[--top];
          // Eigen's vectors do not zero themselves ("= {}" leaves them uninitialised).
          Vec3 pts[kNetSide];
          std::fill(std::begin(pts), std::end(pts), Vec3::Zero());
          for (int k = 0; k <= f.c.degree; ++k)
            pts[k] = f.c.point(k);
          const int n = f.c.degree;
          if (f.valid) {
            if (n >= 1 && !point_nearest_curve(pts, n, p)) {
              continue;  // Algorithm 5: no candidate on this piece
            }
            double dev = 0.0;
            for (int k = 1; k < n; ++k) {
              dev = std::max(dev, (pts[k] - project_on_line(pts[k], pts[0], pts[n])).norm());
            }
            if (dev <= kFlatness * (pts[n] - pts[0]).norm() || f.depth >= kMaxRecursion) {
              newton_on(f.c.param.lo, f.c.param.hi);
              continue;
            }
          } else if (is_valid_polygon(pts, n)) {
            f.valid = true;
          } else if (f.depth >= kMaxRecursion) {
            newton_on(f.c.param.lo, f.c.param.hi);
            continue;
          }
          ++local.subdivisions;
          Frame low{f.c, f.valid, f.depth + 1}, high{f.c, f.valid, f.depth + 1};
          f.c.split(0.5, low.c, high.c);
          stack[top++] = high;
          stack[top++] = low;
        }
      }
    }
  }
  if (stats) stats->add(local);
}

}  // namespace nurbsreg::engine
