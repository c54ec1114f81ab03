// SISL peer (AGPL: this file is compiled into the optional benchmark executable only). s1954
// finds the global minima of the squared distance by substituting the surface into the
// implicit sphere of radius 0 around the point and recursively subdividing the resulting
// scalar spline (SISL's s1921): global and exact, but it builds, subdivides and frees new
// splines for every point.

#include <sisl.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "nurbsreg/engine/decompose.hpp"
#include "peer.hpp"

namespace nurbsreg::bench {
namespace {

using engine::Vec3;

// SISL's coefficient order: the first parameter direction (our u, index i) runs fastest, so
// coefficient (i, j) sits at j * count_u + i; rational surfaces (kind 2) take homogeneous
// coefficients (w x, w y, w z, w).
SISLSurf* to_sisl(const engine::NurbsSurface& input) {
  const engine::NurbsSurface s = engine::clamp(input);
  const bool rational = s.is_rational();
  const int stride = rational ? 4 : 3;
  std::vector<double> coefficients(static_cast<std::size_t>(s.count_u) * s.count_v * stride);
  for (int i = 0; i < s.count_u; ++i) {
    for (int j = 0; j < s.count_v; ++j) {
      double* c = &coefficients[(static_cast<std::size_t>(j) * s.count_u + i) * stride];
      const Vec3& p = s.point(i, j);
      const double w = rational ? s.weight(i, j) : 1.0;
      c[0] = w * p.x();
      c[1] = w * p.y();
      c[2] = w * p.z();
      if (rational) c[3] = w;
    }
  }
  std::vector<double> knots_u = s.knots_u;
  std::vector<double> knots_v = s.knots_v;
  // copy flag 1: SISL copies the arrays, so the vectors may go out of scope.
  SISLSurf* surface = newSurf(s.count_u, s.count_v, s.degree_u + 1, s.degree_v + 1, knots_u.data(),
                              knots_v.data(), coefficients.data(), rational ? 2 : 1, 3, 1);
  if (surface == nullptr) throw std::runtime_error("SISL newSurf failed for \"" + s.name + "\"");
  return surface;
}

bool evaluate(SISLSurf* surface, double u, double v, Vec3& out) {
  double parameter[2] = {u, v};
  int left_u = 0;
  int left_v = 0;
  double value[3];
  int status = 0;
  s1424(surface, 0, 0, parameter, &left_u, &left_v, value, &status);
  if (status < 0) return false;
  out = Vec3(value[0], value[1], value[2]);
  return true;
}

void check_conversion(const engine::NurbsSurface& s, SISLSurf* surface) {
  const auto du = s.domain_u();
  const auto dv = s.domain_v();
  for (int a = 0; a <= 8; ++a) {
    for (int b = 0; b <= 8; ++b) {
      const double u = du.to_parent(a / 8.0);
      const double v = dv.to_parent(b / 8.0);
      const Vec3 ours = s.evaluate(u, v);
      Vec3 theirs;
      const bool ok = evaluate(surface, u, v, theirs);
      const double error = ok ? (ours - theirs).norm() : INFINITY;
      if (!(error <= 1e-9 * (1.0 + ours.norm()))) {
        throw std::runtime_error("SISL conversion of surface \"" + s.name + "\" is off by " +
                                 std::to_string(error));
      }
    }
  }
}

class SislPeer final : public Peer {
 public:
  SislPeer(const engine::Model& model, double epsge) : epsge_(epsge) {
    for (const auto& s : model.surfaces) {
      surfaces_.push_back(to_sisl(s));
      check_conversion(s, surfaces_.back());
    }
  }
  ~SislPeer() override {
    for (SISLSurf* s : surfaces_)
      freeSurf(s);
  }
  SislPeer(const SislPeer&) = delete;
  SislPeer& operator=(const SislPeer&) = delete;

  std::string name() const override { return "SISL s1954"; }

  // s1954 keeps no state between calls and only reads the input surface: s1320 substitutes it
  // into the sphere equation as a new spline, and s1921 subdivides that one.
  void prepare_threads(int) override {}

  void project(std::span<const Vec3> points, std::span<double> distance) override {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 1),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                        for (std::size_t i = range.begin(); i < range.end(); ++i) {
                          distance[i] = project_one(points[i]);
                        }
                      });
  }

 private:
  double project_one(const Vec3& p) const {
    double best_sq = INFINITY;
    double point[3] = {p.x(), p.y(), p.z()};
    for (SISLSurf* surface : surfaces_) {
      int count = 0;
      double* parameters = nullptr;
      int curve_count = 0;
      SISLIntcurve** curves = nullptr;
      int status = 0;
      s1954(surface, point, 3, 1e-15, epsge_, &count, &parameters, &curve_count, &curves, &status);
      auto consider = [&](double u, double v) {
        Vec3 q;
        if (evaluate(surface, u, v, q)) best_sq = std::min(best_sq, (q - p).squaredNorm());
      };
      if (status >= 0) {
        for (int k = 0; k < count; ++k)
          consider(parameters[2 * k], parameters[2 * k + 1]);
        // Closest curves (a whole arc at equal distance): every sampled point is a candidate.
        for (int c = 0; c < curve_count; ++c) {
          const SISLIntcurve* curve = curves[c];
          for (int k = 0; k < curve->ipoint; ++k) {
            consider(curve->epar1[2 * k], curve->epar1[2 * k + 1]);
          }
        }
      }
      std::free(parameters);
      if (curves != nullptr) freeIntcrvlist(curves, curve_count);
    }
    return std::isfinite(best_sq) ? std::sqrt(best_sq) : kNoResult;
  }

  double epsge_;
  std::vector<SISLSurf*> surfaces_;
};

}  // namespace

std::unique_ptr<Peer> make_sisl_peer(const engine::Model& model, double epsge) {
  return std::make_unique<SislPeer>(model, epsge);
}

}  // namespace nurbsreg::bench
