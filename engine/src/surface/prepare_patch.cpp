// The cached squared-distance coefficients of a patch (prepare_patch, PreparedPatch::numerator)
// and the clipping's per-thread scratch.

#include <algorithm>
#include <cassert>
#include <cmath>

#include "bernstein/binomial_table.hpp"
#include "nurbsreg/engine/surface_projection.hpp"
#include "platform/cpu_dispatch.hpp"

namespace nurbsreg::engine {
namespace {

// C(2p, a + c) for p <= kMaxDegree.
constexpr BinomialTable<2 * kMaxDegree> kBinomials;

double binomial(int n, int k) {
  return kBinomials.c[n][k];
}

}  // namespace

SurfaceScratch::SurfaceScratch()
    : grids(static_cast<std::size_t>(kStackCapacity + 1) * 2 * kGridCapacity),
      boxes(kStackCapacity + 1),
      rows(static_cast<std::size_t>(kStackCapacity + 2) * 2 * (2 * kMaxDegree + 1)),
      intervals(kStackCapacity + 1) {
  order.reserve(kDefaultPatchCapacity);
}

NURBSREG_HOT_CLONES
void PreparedPatch::numerator(const Vec3& point, double* out) const {
  const Vec3 q = point - origin;
  const double qq = q.squaredNorm();
  const int count = rows * cols;
  // Structure-of-arrays copy of E: the loop vectorises.
  const double* ex = e_soa.data();
  const double* ey = ex + count;
  const double* ez = ey + count;
  const double qx = 2.0 * q.x(), qy = 2.0 * q.y(), qz = 2.0 * q.z();
  if (!rational) {
    // D == 1 exactly (prepare_patch), so qq * D == qq: the same values without reading D.
    for (int k = 0; k < count; ++k)
      out[k] = g[k] - (qx * ex[k] + qy * ey[k] + qz * ez[k]) + qq;
    return;
  }
  for (int k = 0; k < count; ++k)
    out[k] = g[k] - (qx * ex[k] + qy * ey[k] + qz * ez[k]) + qq * d[k];
}

PreparedPatch prepare_patch(const BezierPatch& patch) {
  assert(patch.degree_u <= kMaxDegree && patch.degree_v <= kMaxDegree);
  PreparedPatch pp;
  pp.patch = patch;
  pp.box = bounding_box(patch);
  pp.sphere = bounding_sphere(patch);
  pp.origin = pp.sphere.center;
  const int p = patch.degree_u, q = patch.degree_v;
  pp.rows = 2 * p + 1;
  pp.cols = 2 * q + 1;
  const double w0 = patch.cw[0][3];
  pp.rational = false;
  pp.unit_weights =
      std::all_of(patch.cw.begin(), patch.cw.end(), [](const Vec4& c) { return c[3] == 1.0; });
  for (const Vec4& c : patch.cw) {
    if (std::abs(c[3] - w0) > 1e-14 * w0) pp.rational = true;
  }
  const int count = pp.rows * pp.cols;
  pp.d.assign(count, 0.0);
  pp.g.assign(count, 0.0);
  pp.e.assign(count, Vec3::Zero());
  // Homogeneous points relative to the origin, w (P - o); weights 1 for polynomial patches.
  std::vector<Vec3> pw(patch.cw.size());
  std::vector<double> w(patch.cw.size());
  for (std::size_t k = 0; k < patch.cw.size(); ++k) {
    const Vec4& c = patch.cw[k];
    w[k] = pp.rational ? c[3] : 1.0;
    pw[k] = w[k] * (c.head<3>() / c[3] - pp.origin);
  }
  // Bernstein product identity B_a^p B_c^p = C(p,a) C(p,c) / C(2p,a+c) B_{a+c}^{2p}.
  const int stride = q + 1;
  for (int a = 0; a <= p; ++a) {
    for (int c = 0; c <= p; ++c) {
      const double bu = binomial(p, a) * binomial(p, c) / binomial(2 * p, a + c);
      for (int b = 0; b <= q; ++b) {
        for (int dd = 0; dd <= q; ++dd) {
          const double beta = bu * binomial(q, b) * binomial(q, dd) / binomial(2 * q, b + dd);
          const int k = (a + c) * pp.cols + (b + dd);
          const int ab = a * stride + b, cd = c * stride + dd;
          pp.d[k] += beta * w[ab] * w[cd];
          pp.g[k] += beta * pw[ab].dot(pw[cd]);
          pp.e[k] += beta * 0.5 * (w[cd] * pw[ab] + w[ab] * pw[cd]);
        }
      }
    }
  }
  if (!pp.rational) std::fill(pp.d.begin(), pp.d.end(), 1.0);
  pp.e_soa.resize(3 * static_cast<std::size_t>(count));
  for (int k = 0; k < count; ++k) {
    for (int c = 0; c < 3; ++c)
      pp.e_soa[static_cast<std::size_t>(c * count + k)] = pp.e[k][c];
  }
  if (pp.rational) {
    const auto w = [&](int i, int j) { return pp.d[static_cast<std::size_t>(i * pp.cols + j)]; };
    for (int i = 0; i < pp.rows; ++i) {
      for (int j = 0; j < pp.cols; ++j) {
        if (i + 2 < pp.rows) {
          pp.d_ss = std::max(pp.d_ss, std::abs(w(i + 2, j) - 2.0 * w(i + 1, j) + w(i, j)));
        }
        if (j + 2 < pp.cols) {
          pp.d_tt = std::max(pp.d_tt, std::abs(w(i, j + 2) - 2.0 * w(i, j + 1) + w(i, j)));
        }
        if (i + 1 < pp.rows && j + 1 < pp.cols) {
          pp.d_st =
              std::max(pp.d_st, std::abs(w(i + 1, j + 1) - w(i + 1, j) - w(i, j + 1) + w(i, j)));
        }
      }
    }
  }
  const auto at = [&](int i, int j) { return pp.e[static_cast<std::size_t>(i * pp.cols + j)]; };
  for (int i = 0; i < pp.rows; ++i) {
    for (int j = 0; j < pp.cols; ++j) {
      if (i + 1 < pp.rows) pp.e_s = std::max(pp.e_s, (at(i + 1, j) - at(i, j)).norm());
      if (j + 1 < pp.cols) pp.e_t = std::max(pp.e_t, (at(i, j + 1) - at(i, j)).norm());
      if (i + 2 < pp.rows) {
        pp.e_ss = std::max(pp.e_ss, (at(i + 2, j) - 2.0 * at(i + 1, j) + at(i, j)).norm());
      }
      if (j + 2 < pp.cols) {
        pp.e_tt = std::max(pp.e_tt, (at(i, j + 2) - 2.0 * at(i, j + 1) + at(i, j)).norm());
      }
      if (i + 1 < pp.rows && j + 1 < pp.cols) {
        pp.e_st =
            std::max(pp.e_st, (at(i + 1, j + 1) - at(i + 1, j) - at(i, j + 1) + at(i, j)).norm());
      }
    }
  }
  return pp;
}

}  // namespace nurbsreg::engine
