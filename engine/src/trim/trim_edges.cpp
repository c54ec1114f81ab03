// trim_edges(): the 3-D edges of a trimmed face. A degree-1 uv curve without a CAD edge is
// mapped exactly: on a piece of the line inside one Bézier patch (s, r local patch parameters),
// the homogeneous uv line gives w(t) s(t) and w(t) (1 - s(t)) as linear polynomials with
// non-negative Bernstein coefficients, so w^p B_i^p(s(t)) = C(p,i) (w s)^i (w (1 - s))^(p-i) is a
// polynomial of degree p whose Bernstein coefficients are products and sums of non-negative
// numbers (no cancellation); likewise in v. The image's homogeneous form
//   H(t) = w(t)^(p+q) S^w(s(t), r(t)) = sum_ij P^w_ij [w^p B_i^p(s)] [w^q B_j^q(r)]
// is a polynomial of degree p + q, and S(uv(t)) = H(t) / H_w(t). Its weights are positive (each
// Bernstein coefficient of H_w is >= min w_ij times that of w^(p+q) > 0).

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "bernstein/binomial_table.hpp"
#include "nurbsreg/engine/decompose.hpp"
#include "nurbsreg/engine/trim_region.hpp"

namespace nurbsreg::engine {
namespace {

constexpr int kMaxProduct = 2 * kMaxDegree;

constexpr BinomialTable<kMaxProduct> kBinomials;

double binomial(int n, int k) {
  return kBinomials.c[n][k];
}

// Bernstein coefficients of the product of polynomials of degrees m and n given in Bernstein
// form (all coefficients here are non-negative: the sums do not cancel).
void bernstein_product(const double* a, int m, const double* b, int n, double* out) {
  for (int k = 0; k <= m + n; ++k)
    out[k] = 0.0;
  for (int i = 0; i <= m; ++i) {
    for (int j = 0; j <= n; ++j)
      out[i + j] += binomial(m, i) * binomial(n, j) * a[i] * b[j];
  }
  for (int k = 0; k <= m + n; ++k)
    out[k] /= binomial(m + n, k);
}

// basis[i][k]: Bernstein coefficient k (degree `degree`) of w^degree B_i^degree(s(t)), where
// w s and w (1 - s) are linear with end values (one_a, one_b) and (zero_a, zero_b).
void restricted_basis(int degree, double one_a, double one_b, double zero_a, double zero_b,
                      double (*basis)[kMaxDegree + 1]) {
  const double one[2] = {one_a, one_b}, zero[2] = {zero_a, zero_b};
  // powers_one[i] = (w s)^i, powers_zero[i] = (w (1 - s))^i, each of degree i.
  double powers_one[kMaxDegree + 1][kMaxDegree + 1], powers_zero[kMaxDegree + 1][kMaxDegree + 1];
  powers_one[0][0] = powers_zero[0][0] = 1.0;
  for (int i = 1; i <= degree; ++i) {
    bernstein_product(powers_one[i - 1], i - 1, one, 1, powers_one[i]);
    bernstein_product(powers_zero[i - 1], i - 1, zero, 1, powers_zero[i]);
  }
  for (int i = 0; i <= degree; ++i) {
    bernstein_product(powers_one[i], i, powers_zero[degree - i], degree - i, basis[i]);
    const double c = binomial(degree, i);
    for (int k = 0; k <= degree; ++k)
      basis[i][k] *= c;
  }
}

// Bernstein degree elevation by one, in place (size n + 2 available).
void elevate(Vec4* c, int n) {
  Vec4 next[kMaxProduct + 2];
  next[0] = c[0];
  next[n + 1] = c[n];
  for (int k = 1; k <= n; ++k) {
    const double a = static_cast<double>(k) / (n + 1);
    next[k] = a * c[k - 1] + (1.0 - a) * c[k];
  }
  for (int k = 0; k <= n + 1; ++k)
    c[k] = next[k];
}

struct Segment {
  double t0, t1;
  int degree;
  Vec4 cw[kMaxProduct + 1];
};

// Index of the span among `breaks` (sorted, size spans + 1) that holds x, clamped.
int span_of(const std::vector<double>& breaks, double x) {
  const auto it = std::upper_bound(breaks.begin() + 1, breaks.end() - 1, x);
  return static_cast<int>(it - breaks.begin()) - 1;
}

class LineMapper {
 public:
  explicit LineMapper(const NurbsSurface& surface) : surface_(surface) {
    patches_ = decompose(surface, &spans_u_, &spans_v_);
    for (int a = 0; a < spans_u_; ++a)
      breaks_u_.push_back(patches_[static_cast<std::size_t>(a) * spans_v_].param_u.lo);
    breaks_u_.push_back(patches_.back().param_u.hi);
    for (int b = 0; b < spans_v_; ++b)
      breaks_v_.push_back(patches_[b].param_v.lo);
    breaks_v_.push_back(patches_.back().param_v.hi);
  }

  NurbsCurve map(const NurbsCurve& uv, const std::string& what) const {
    std::vector<Segment> segments;
    for (int i = 1; i < uv.count(); ++i) {
      const double k0 = uv.knots[i], k1 = uv.knots[i + 1];
      if (!(k1 > k0)) continue;
      map_span(uv.homogeneous(i - 1), uv.homogeneous(i), k0, k1, segments);
    }
    int degree = 0;
    for (const Segment& s : segments)
      degree = std::max(degree, s.degree);
    if (degree > kMaxDegree) {
      throw std::invalid_argument(what + ": its exact 3-D image has degree " +
                                  std::to_string(degree) + " > " + std::to_string(kMaxDegree) +
                                  " (surface degrees " + std::to_string(surface_.degree_u) + " + " +
                                  std::to_string(surface_.degree_v) + ")");
    }
    degree = std::max(degree, 1);
    NurbsCurve edge;
    edge.name = what;
    edge.degree = degree;
    edge.dimension = 3;
    std::vector<Vec4> cw;
    for (std::size_t k = 0; k < segments.size(); ++k) {
      Segment& s = segments[k];
      while (s.degree < degree)
        elevate(s.cw, s.degree++);
      if (k == 0) {
        edge.knots.assign(degree + 1, s.t0);
        cw.push_back(s.cw[0]);
      } else {
        edge.knots.insert(edge.knots.end(), degree, s.t0);
        // The joint: both sides compute H at the same (u, v, w); average the rounding.
        cw.back() = 0.5 * (cw.back() + s.cw[0]);
      }
      for (int j = 1; j <= degree; ++j)
        cw.push_back(s.cw[j]);
    }
    edge.knots.insert(edge.knots.end(), degree + 1, segments.back().t1);
    const bool rational = surface_.is_rational() || uv.is_rational();
    for (const Vec4& h : cw) {
      edge.control_points.push_back(h.head<3>() / h[3]);
      if (rational) edge.weights.push_back(h[3]);
    }
    return edge;
  }

 private:
  // The homogeneous uv line from ha (t = k0) to hb (t = k1), cut at the surface's knot lines.
  void map_span(const Vec4& ha, const Vec4& hb, double k0, double k1,
                std::vector<Segment>& out) const {
    // tau in (0, 1) where u (or v) crosses a break: (1-tau) wa (ua - U) + tau wb (ub - U) = 0,
    // with w u linear in tau. The domain's ends count too: beyond them S is clamped, which the
    // clamped local parameters of the end patches reproduce exactly.
    std::vector<double> cuts = {0.0, 1.0};
    auto add_cuts = [&](const std::vector<double>& breaks, int axis) {
      for (std::size_t k = 0; k < breaks.size(); ++k) {
        const double fa = ha[axis] - breaks[k] * ha[3], fb = hb[axis] - breaks[k] * hb[3];
        if ((fa < 0.0 && fb > 0.0) || (fa > 0.0 && fb < 0.0)) cuts.push_back(fa / (fa - fb));
      }
    };
    add_cuts(breaks_u_, 0);
    add_cuts(breaks_v_, 1);
    std::sort(cuts.begin(), cuts.end());
    // Through a knot intersection the u and v cuts coincide up to rounding: merge them.
    std::vector<double> unique = {0.0};
    for (double c : cuts) {
      if (c - unique.back() > 1e-13) unique.push_back(c);
    }
    unique.back() = 1.0;
    for (std::size_t k = 0; k + 1 < unique.size(); ++k) {
      const double a = unique[k], b = unique[k + 1];
      const Vec4 pa = (1.0 - a) * ha + a * hb, pb = (1.0 - b) * ha + b * hb;
      Segment s;
      s.t0 = k0 + a * (k1 - k0);
      s.t1 = k == unique.size() - 2 ? k1 : k0 + b * (k1 - k0);
      if (k == 0) s.t0 = k0;
      map_piece(pa, pb, s);
      out.push_back(s);
    }
  }

  // The exact image of the homogeneous line piece pa -> pb, inside one patch.
  void map_piece(const Vec4& pa, const Vec4& pb, Segment& s) const {
    const Vec4 mid = 0.5 * (pa + pb);
    const int a = span_of(breaks_u_, mid[0] / mid[3]);
    const int b = span_of(breaks_v_, mid[1] / mid[3]);
    const BezierPatch& patch = patches_[static_cast<std::size_t>(a) * spans_v_ + b];
    const int p = patch.degree_u, q = patch.degree_v;
    // Local patch parameters at the ends, clamped against rounding (and against a line that
    // leaves the domain, where S itself is clamped).
    auto local = [](double x, const ParamInterval& iv) {
      return std::clamp(iv.to_local(x), 0.0, 1.0);
    };
    const double sa = local(pa[0] / pa[3], patch.param_u), sb = local(pb[0] / pb[3], patch.param_u);
    const double ra = local(pa[1] / pa[3], patch.param_v), rb = local(pb[1] / pb[3], patch.param_v);
    // A piece along an iso line (constant s, constant w) has degree 0 in that direction.
    const bool same_w = pa[3] == pb[3];
    const int dp = (same_w && sa == sb) ? 0 : p;
    const int dq = (same_w && ra == rb) ? 0 : q;
    double bu[kMaxDegree + 1][kMaxDegree + 1], bv[kMaxDegree + 1][kMaxDegree + 1];
    double cu[kMaxDegree + 1], cv[kMaxDegree + 1];  // degree-0 case: plain B_i^p(s) w^p
    const double wa = pa[3], wb = pb[3];
    if (dp > 0) {
      restricted_basis(p, wa * sa, wb * sb, wa * (1.0 - sa), wb * (1.0 - sb), bu);
    } else {
      bernstein(p, sa, cu);
      for (int i = 0; i <= p; ++i)
        bu[i][0] = cu[i] * std::pow(wa, p);
    }
    if (dq > 0) {
      restricted_basis(q, wa * ra, wb * rb, wa * (1.0 - ra), wb * (1.0 - rb), bv);
    } else {
      bernstein(q, ra, cv);
      for (int j = 0; j <= q; ++j)
        bv[j][0] = cv[j] * std::pow(wa, q);
    }
    s.degree = dp + dq;
    for (int k = 0; k <= s.degree; ++k)
      s.cw[k].setZero();
    double prod[kMaxProduct + 1];
    for (int i = 0; i <= p; ++i) {
      for (int j = 0; j <= q; ++j) {
        bernstein_product(bu[i], dp, bv[j], dq, prod);
        const Vec4& h = patch.at(i, j);
        for (int k = 0; k <= s.degree; ++k)
          s.cw[k] += prod[k] * h;
      }
    }
  }

  const NurbsSurface& surface_;
  std::vector<BezierPatch> patches_;
  int spans_u_ = 0, spans_v_ = 0;
  std::vector<double> breaks_u_, breaks_v_;
};

}  // namespace

std::vector<TrimEdge> trim_edges(const NurbsSurface& surface) {
  std::vector<TrimEdge> edges;
  std::optional<LineMapper> mapper;
  for (std::size_t l = 0; l < surface.trim_loops.size(); ++l) {
    const TrimLoop& loop = surface.trim_loops[l];
    for (std::size_t c = 0; c < loop.curves.size(); ++c) {
      const TrimCurve& curve = loop.curves[c];
      TrimEdge e;
      e.loop = static_cast<int>(l);
      e.curve = static_cast<int>(c);
      const std::string what = "surface '" + surface.name + "' trim_loops[" + std::to_string(l) +
                               "].curves[" + std::to_string(c) + "]";
      if (curve.edge) {
        e.edge = *curve.edge;
      } else if (curve.uv.degree == 1) {
        if (!mapper) mapper.emplace(surface);
        e.edge = mapper->map(curve.uv, what);
      } else {
        throw std::invalid_argument(what + ": a uv curve of degree " +
                                    std::to_string(curve.uv.degree) + " needs its 3-D edge");
      }
      edges.push_back(std::move(e));
    }
  }
  return edges;
}

}  // namespace nurbsreg::engine
