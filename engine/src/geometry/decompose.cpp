#include "nurbsreg/engine/decompose.hpp"

#include <algorithm>
#include <cassert>

#include "geometry/basis.hpp"

namespace nurbsreg::engine {
namespace {

// The NURBS Book A5.4 (RefineKnotVectCurve) on homogeneous points. `insert` sorted, r+1 values.
void refine(int degree, const std::vector<double>& knots, const std::vector<Vec4>& pw,
            std::span<const double> insert, std::vector<double>& knots_out,
            std::vector<Vec4>& pw_out) {
  const int p = degree;
  const int n = static_cast<int>(pw.size()) - 1;
  const int m = n + p + 1;
  if (insert.empty()) {
    knots_out = knots;
    pw_out = pw;
    return;
  }
  const int r = static_cast<int>(insert.size()) - 1;
  const int a = find_span(p, knots, n + 1, insert[0]);
  const int b = find_span(p, knots, n + 1, insert[r]) + 1;
  knots_out.assign(m + r + 2, 0.0);
  pw_out.assign(n + r + 2, Vec4::Zero());
  for (int j = 0; j <= a - p; ++j)
    pw_out[j] = pw[j];
  for (int j = b - 1; j <= n; ++j)
    pw_out[j + r + 1] = pw[j];
  for (int j = 0; j <= a; ++j)
    knots_out[j] = knots[j];
  for (int j = b + p; j <= m; ++j)
    knots_out[j + r + 1] = knots[j];
  int i = b + p - 1;
  int k = b + p + r;
  for (int j = r; j >= 0; --j) {
    while (insert[j] <= knots[i] && i > a) {
      pw_out[k - p - 1] = pw[i - p - 1];
      knots_out[k] = knots[i];
      --k;
      --i;
    }
    pw_out[k - p - 1] = pw_out[k - p];
    for (int l = 1; l <= p; ++l) {
      const int ind = k - p + l;
      double alpha = knots_out[k + l] - insert[j];
      if (alpha == 0.0) {
        pw_out[ind - 1] = pw_out[ind];
      } else {
        alpha /= knots_out[k + l] - knots[i - p + l];
        pw_out[ind - 1] = alpha * pw_out[ind - 1] + (1.0 - alpha) * pw_out[ind];
      }
    }
    knots_out[k] = insert[j];
    --k;
  }
}

int multiplicity(const std::vector<double>& knots, double u) {
  return static_cast<int>(std::count(knots.begin(), knots.end(), u));
}

// Knots to insert so that every distinct value in `targets` reaches multiplicity `wanted`.
std::vector<double> to_reach(const std::vector<double>& knots, const std::vector<double>& targets,
                             int wanted) {
  std::vector<double> insert;
  for (double u : targets) {
    for (int s = multiplicity(knots, u); s < wanted; ++s)
      insert.push_back(u);
  }
  std::sort(insert.begin(), insert.end());
  return insert;
}

// Restricts a homogeneous control polygon to [lo, hi] (within its domain): inserts lo and hi to
// multiplicity `degree`, then drops the knots and points outside (the curve is unchanged on
// [lo, hi], its end knots clamped there).
void restrict_polygon(int degree, std::vector<double>& knots, std::vector<Vec4>& pw, double lo,
                      double hi) {
  std::vector<double> new_knots;
  std::vector<Vec4> new_pw;
  refine(degree, knots, pw, to_reach(knots, {lo, hi}, degree), new_knots, new_pw);
  // With `lo` at indices [first, last] (multiplicity >= degree), the clamped vector starts
  // at last - degree with value lo; likewise it ends at first_hi + degree.
  const auto lo_last = static_cast<int>(std::upper_bound(new_knots.begin(), new_knots.end(), lo) -
                                        new_knots.begin() - 1);
  const auto hi_first = static_cast<int>(std::lower_bound(new_knots.begin(), new_knots.end(), hi) -
                                         new_knots.begin());
  const int start = lo_last - degree;
  const int end = hi_first + degree;  // inclusive knot index
  assert(start >= 0 && end < static_cast<int>(new_knots.size()));
  knots.assign(new_knots.begin() + start, new_knots.begin() + end + 1);
  knots.front() = lo;
  knots.back() = hi;
  const int new_count = static_cast<int>(knots.size()) - degree - 1;
  pw.assign(new_pw.begin() + start, new_pw.begin() + start + new_count);
}

// Clamps a homogeneous control polygon: restricted to its own domain.
void clamp_polygon(int degree, std::vector<double>& knots, std::vector<Vec4>& pw) {
  const double lo = knots[static_cast<std::size_t>(degree)];
  const double hi = knots[pw.size()];
  restrict_polygon(degree, knots, pw, lo, hi);
}

std::vector<double> distinct_interior(const std::vector<double>& knots, int degree, int count) {
  std::vector<double> values;
  const double lo = knots[degree];
  const double hi = knots[count];
  for (double u : knots) {
    if (u > lo && u < hi && (values.empty() || values.back() != u)) values.push_back(u);
  }
  return values;
}

std::vector<Vec4> homogeneous_points(const NurbsCurve& c) {
  std::vector<Vec4> pw(c.count());
  for (int i = 0; i < c.count(); ++i)
    pw[i] = c.homogeneous(i);
  return pw;
}

NurbsCurve from_homogeneous(const NurbsCurve& like, std::vector<double> knots,
                            const std::vector<Vec4>& pw) {
  NurbsCurve out;
  out.name = like.name;
  out.degree = like.degree;
  out.dimension = like.dimension;
  out.knots = std::move(knots);
  out.control_points.resize(pw.size());
  if (like.is_rational()) out.weights.resize(pw.size());
  for (std::size_t i = 0; i < pw.size(); ++i) {
    out.control_points[i] = pw[i].head<3>() / pw[i][3];
    if (like.is_rational()) out.weights[i] = pw[i][3];
  }
  return out;
}

// A surface as a grid of homogeneous points, refined along one direction line by line.
struct HomogeneousGrid {
  int count_u = 0;
  int count_v = 0;
  std::vector<Vec4> pw;  // row-major like NurbsSurface
};

HomogeneousGrid grid_of(const NurbsSurface& s) {
  HomogeneousGrid g{s.count_u, s.count_v, std::vector<Vec4>(s.control_points.size())};
  for (int i = 0; i < s.count_u; ++i) {
    for (int j = 0; j < s.count_v; ++j)
      g.pw[i * s.count_v + j] = s.homogeneous(i, j);
  }
  return g;
}

NurbsSurface surface_from_grid(const NurbsSurface& like, std::vector<double> knots_u,
                               std::vector<double> knots_v, const HomogeneousGrid& g) {
  NurbsSurface out;
  out.name = like.name;
  out.degree_u = like.degree_u;
  out.degree_v = like.degree_v;
  out.knots_u = std::move(knots_u);
  out.knots_v = std::move(knots_v);
  out.count_u = g.count_u;
  out.count_v = g.count_v;
  out.control_points.resize(g.pw.size());
  if (like.is_rational()) out.weights.resize(g.pw.size());
  for (std::size_t k = 0; k < g.pw.size(); ++k) {
    out.control_points[k] = g.pw[k].head<3>() / g.pw[k][3];
    if (like.is_rational()) out.weights[k] = g.pw[k][3];
  }
  return out;
}

// `refined` (a new knot vector of `s`: the same function of (u, v)) with s's face: its trim loops
// and orientation.
NurbsSurface same_face(const NurbsSurface& s, NurbsSurface refined) {
  refined.trim_loops = s.trim_loops;
  refined.reversed = s.reversed;
  return refined;
}

// Applies `op` (knots, line of points) -> (new knots, new line) to every line along u
// (along_u) or v, rebuilding the grid. All lines get the same new knot vector.
template <typename Op>
std::vector<double> transform_lines(HomogeneousGrid& g, bool along_u, Op op) {
  const int lines = along_u ? g.count_v : g.count_u;
  const int length = along_u ? g.count_u : g.count_v;
  std::vector<std::vector<Vec4>> result(lines);
  std::vector<double> knots_out;
  for (int line = 0; line < lines; ++line) {
    std::vector<Vec4> pts(length);
    for (int k = 0; k < length; ++k) {
      pts[k] = along_u ? g.pw[k * g.count_v + line] : g.pw[line * g.count_v + k];
    }
    knots_out = op(pts);
    result[line] = std::move(pts);
  }
  const int new_length = static_cast<int>(result[0].size());
  if (along_u) {
    g.count_u = new_length;
  } else {
    g.count_v = new_length;
  }
  g.pw.assign(static_cast<std::size_t>(g.count_u) * g.count_v, Vec4::Zero());
  for (int line = 0; line < lines; ++line) {
    for (int k = 0; k < new_length; ++k) {
      (along_u ? g.pw[k * g.count_v + line] : g.pw[line * g.count_v + k]) = result[line][k];
    }
  }
  return knots_out;
}

}  // namespace

NurbsCurve refine_knots(const NurbsCurve& curve, std::span<const double> insert) {
  std::vector<double> knots;
  std::vector<Vec4> pw;
  refine(curve.degree, curve.knots, homogeneous_points(curve), insert, knots, pw);
  return from_homogeneous(curve, std::move(knots), pw);
}

NurbsCurve insert_knot(const NurbsCurve& curve, double u, int times) {
  const std::vector<double> insert(times, u);
  return refine_knots(curve, insert);
}

NurbsCurve clamp(const NurbsCurve& curve) {
  std::vector<double> knots = curve.knots;
  std::vector<Vec4> pw = homogeneous_points(curve);
  clamp_polygon(curve.degree, knots, pw);
  return from_homogeneous(curve, std::move(knots), pw);
}

NurbsSurface refine_knots_u(const NurbsSurface& s, std::span<const double> insert) {
  HomogeneousGrid g = grid_of(s);
  auto knots = transform_lines(g, true, [&](std::vector<Vec4>& pts) {
    std::vector<double> k;
    std::vector<Vec4> out;
    refine(s.degree_u, s.knots_u, pts, insert, k, out);
    pts = std::move(out);
    return k;
  });
  return same_face(s, surface_from_grid(s, std::move(knots), s.knots_v, g));
}

NurbsSurface refine_knots_v(const NurbsSurface& s, std::span<const double> insert) {
  HomogeneousGrid g = grid_of(s);
  auto knots = transform_lines(g, false, [&](std::vector<Vec4>& pts) {
    std::vector<double> k;
    std::vector<Vec4> out;
    refine(s.degree_v, s.knots_v, pts, insert, k, out);
    pts = std::move(out);
    return k;
  });
  return same_face(s, surface_from_grid(s, s.knots_u, std::move(knots), g));
}

NurbsSurface clamp(const NurbsSurface& s) {
  HomogeneousGrid g = grid_of(s);
  auto knots_u = transform_lines(g, true, [&](std::vector<Vec4>& pts) {
    std::vector<double> k = s.knots_u;
    clamp_polygon(s.degree_u, k, pts);
    return k;
  });
  auto knots_v = transform_lines(g, false, [&](std::vector<Vec4>& pts) {
    std::vector<double> k = s.knots_v;
    clamp_polygon(s.degree_v, k, pts);
    return k;
  });
  return surface_from_grid(s, std::move(knots_u), std::move(knots_v), g);
}

NurbsSurface restrict_domain(const NurbsSurface& s, ParamInterval u, ParamInterval v) {
  HomogeneousGrid g = grid_of(s);
  auto knots_u = transform_lines(g, true, [&](std::vector<Vec4>& pts) {
    std::vector<double> k = s.knots_u;
    restrict_polygon(s.degree_u, k, pts, u.lo, u.hi);
    return k;
  });
  auto knots_v = transform_lines(g, false, [&](std::vector<Vec4>& pts) {
    std::vector<double> k = s.knots_v;
    restrict_polygon(s.degree_v, k, pts, v.lo, v.hi);
    return k;
  });
  NurbsSurface out = surface_from_grid(s, std::move(knots_u), std::move(knots_v), g);
  out.reversed = s.reversed;
  return out;
}

std::vector<BezierCurve> decompose(const NurbsCurve& curve) {
  assert(curve.degree <= kMaxDegree);
  const NurbsCurve c = clamp(curve);
  const int p = c.degree;
  const std::vector<double> interior = distinct_interior(c.knots, p, c.count());
  std::vector<double> knots;
  std::vector<Vec4> pw;
  refine(p, c.knots, homogeneous_points(c), to_reach(c.knots, interior, p), knots, pw);
  // Breakpoints: lo, interior..., hi; piece k uses points [k p, k p + p].
  std::vector<double> breaks;
  breaks.push_back(c.knots.front());
  breaks.insert(breaks.end(), interior.begin(), interior.end());
  breaks.push_back(c.knots.back());
  std::vector<BezierCurve> pieces(breaks.size() - 1);
  for (std::size_t k = 0; k < pieces.size(); ++k) {
    pieces[k].degree = p;
    for (int i = 0; i <= p; ++i)
      pieces[k].cw[i] = pw[k * p + i];
    pieces[k].param = {breaks[k], breaks[k + 1]};
  }
  return pieces;
}

std::vector<BezierPatch> decompose(const NurbsSurface& surface, int* spans_u, int* spans_v) {
  const NurbsSurface s = clamp(surface);
  const std::vector<double> inner_u = distinct_interior(s.knots_u, s.degree_u, s.count_u);
  const std::vector<double> inner_v = distinct_interior(s.knots_v, s.degree_v, s.count_v);
  const NurbsSurface r = refine_knots_v(refine_knots_u(s, to_reach(s.knots_u, inner_u, s.degree_u)),
                                        to_reach(s.knots_v, inner_v, s.degree_v));
  auto breaks_of = [](const std::vector<double>& knots, const std::vector<double>& inner) {
    std::vector<double> b{knots.front()};
    b.insert(b.end(), inner.begin(), inner.end());
    b.push_back(knots.back());
    return b;
  };
  const std::vector<double> bu = breaks_of(s.knots_u, inner_u);
  const std::vector<double> bv = breaks_of(s.knots_v, inner_v);
  const int nu = static_cast<int>(bu.size()) - 1;
  const int nv = static_cast<int>(bv.size()) - 1;
  if (spans_u) *spans_u = nu;
  if (spans_v) *spans_v = nv;
  const int p = s.degree_u;
  const int q = s.degree_v;
  std::vector<BezierPatch> patches(static_cast<std::size_t>(nu) * nv);
  for (int a = 0; a < nu; ++a) {
    for (int b = 0; b < nv; ++b) {
      BezierPatch& patch = patches[a * nv + b];
      patch.degree_u = p;
      patch.degree_v = q;
      patch.cw.resize((p + 1) * (q + 1));
      for (int i = 0; i <= p; ++i) {
        for (int j = 0; j <= q; ++j)
          patch.cw[i * (q + 1) + j] = r.homogeneous(a * p + i, b * q + j);
      }
      patch.param_u = {bu[a], bu[a + 1]};
      patch.param_v = {bv[b], bv[b + 1]};
    }
  }
  return patches;
}

}  // namespace nurbsreg::engine
