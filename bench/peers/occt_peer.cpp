// OpenCASCADE peer: GeomAPI_ProjectPointOnSurf, the projector an OCCT user would call, one per
// thread and surface, initialised once per surface (Init(surface, bounds, algo)) and then
// Perform(point) per point. Extrema_GenExtPS returns orthogonal projections only (zeros of the
// gradient of the distance found from a sample grid), so a closest point on a boundary edge,
// corner, seam or pole is found only by chance: the driver counts those misses apart.

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Standard_Failure.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColStd_Array2OfReal.hxx>
#include <TColgp_Array2OfPnt.hxx>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "nurbsreg/engine/decompose.hpp"
#include "peer.hpp"

namespace nurbsreg::bench {
namespace {

using engine::Vec3;

// OCCT stores a knot vector as distinct knots plus multiplicities, 1-based.
struct SplitKnots {
  TColStd_Array1OfReal values;
  TColStd_Array1OfInteger mults;
};
SplitKnots split_knots(const std::vector<double>& knots) {
  std::vector<double> distinct;
  std::vector<int> count;
  for (const double k : knots) {
    if (!distinct.empty() && k == distinct.back()) {
      ++count.back();
    } else {
      distinct.push_back(k);
      count.push_back(1);
    }
  }
  const int n = static_cast<int>(distinct.size());
  SplitKnots out{TColStd_Array1OfReal(1, n), TColStd_Array1OfInteger(1, n)};
  for (int k = 0; k < n; ++k) {
    out.values.SetValue(k + 1, distinct[k]);
    out.mults.SetValue(k + 1, count[k]);
  }
  return out;
}

Handle(Geom_BSplineSurface) to_occt(const engine::NurbsSurface& input) {
  // OCCT needs end knots of multiplicity degree + 1 on a non-periodic surface.
  const engine::NurbsSurface s = engine::clamp(input);
  TColgp_Array2OfPnt poles(1, s.count_u, 1, s.count_v);
  TColStd_Array2OfReal weights(1, s.count_u, 1, s.count_v);
  for (int i = 0; i < s.count_u; ++i) {
    for (int j = 0; j < s.count_v; ++j) {
      // Cartesian poles and separate weights (not homogeneous), OCCT's convention.
      const Vec3& p = s.point(i, j);
      poles.SetValue(i + 1, j + 1, gp_Pnt(p.x(), p.y(), p.z()));
      weights.SetValue(i + 1, j + 1, s.weight(i, j));
    }
  }
  const SplitKnots u = split_knots(s.knots_u);
  const SplitKnots v = split_knots(s.knots_v);
  if (s.is_rational()) {
    return new Geom_BSplineSurface(poles, weights, u.values, v.values, u.mults, v.mults, s.degree_u,
                                   s.degree_v);
  }
  return new Geom_BSplineSurface(poles, u.values, v.values, u.mults, v.mults, s.degree_u,
                                 s.degree_v);
}

// The conversion must not change the geometry: compare with our evaluation on a grid.
void check_conversion(const engine::NurbsSurface& s, const Handle(Geom_BSplineSurface) & g) {
  const auto du = s.domain_u();
  const auto dv = s.domain_v();
  for (int a = 0; a <= 8; ++a) {
    for (int b = 0; b <= 8; ++b) {
      const double u = du.to_parent(a / 8.0);
      const double v = dv.to_parent(b / 8.0);
      const Vec3 ours = s.evaluate(u, v);
      const gp_Pnt theirs = g->Value(u, v);
      const double error = (ours - Vec3(theirs.X(), theirs.Y(), theirs.Z())).norm();
      if (!(error <= 1e-9 * (1.0 + ours.norm()))) {
        throw std::runtime_error("OCCT conversion of surface \"" + s.name + "\" is off by " +
                                 std::to_string(error));
      }
    }
  }
}

class OcctPeer final : public Peer {
 public:
  OcctPeer(const engine::Model& model, bool tree) : tree_(tree) {
    for (const auto& s : model.surfaces) {
      surfaces_.push_back(to_occt(s));
      check_conversion(s, surfaces_.back());
    }
  }

  std::string name() const override { return tree_ ? "OCCT Extrema Tree" : "OCCT Extrema Grad"; }

  void prepare_threads(int max_threads) override {
    // One projector per thread and surface, each on its own copy of the surface so no
    // evaluation cache or reference count is shared between threads.
    while (static_cast<int>(slots_.size()) < max_threads) {
      std::vector<std::unique_ptr<GeomAPI_ProjectPointOnSurf>> per_surface;
      for (const auto& g : surfaces_) {
        Handle(Geom_BSplineSurface) copy = Handle(Geom_BSplineSurface)::DownCast(g->Copy());
        double u0, u1, v0, v1;
        copy->Bounds(u0, u1, v0, v1);
        auto projector = std::make_unique<GeomAPI_ProjectPointOnSurf>();
        projector->Init(copy, u0, u1, v0, v1, tree_ ? Extrema_ExtAlgo_Tree : Extrema_ExtAlgo_Grad);
        // Extrema fills part of its sampling (grid, tree) lazily on the first Perform: one call
        // here so that counts as preparation, as it would for a long-lived projector.
        projector->Perform(copy->Value(0.5 * (u0 + u1), 0.5 * (v0 + v1)));
        per_surface.push_back(std::move(projector));
      }
      slots_.push_back(std::move(per_surface));
    }
  }

  void project(std::span<const Vec3> points, std::span<double> distance) override {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 16),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                        // Arena slots are exclusive while a task runs: the slot's projectors are
                        // ours.
                        auto& projectors = slots_.at(tbb::this_task_arena::current_thread_index());
                        for (std::size_t i = range.begin(); i < range.end(); ++i) {
                          const gp_Pnt p(points[i].x(), points[i].y(), points[i].z());
                          double best = kNoResult;
                          for (auto& projector : projectors) {
                            try {
                              projector->Perform(p);
                              if (projector->NbPoints() > 0)
                                best = std::min(best, projector->LowerDistance());
                            } catch (const Standard_Failure&) {
                              // OCCT signals some degenerate cases by exception: no answer for this
                              // point.
                            }
                          }
                          distance[i] = best;
                        }
                      });
  }

 private:
  bool tree_;
  std::vector<Handle(Geom_BSplineSurface)> surfaces_;
  std::vector<std::vector<std::unique_ptr<GeomAPI_ProjectPointOnSurf>>> slots_;
};

}  // namespace

std::unique_ptr<Peer> make_occt_peer(const engine::Model& model, bool tree) {
  return std::make_unique<OcctPeer>(model, tree);
}

}  // namespace nurbsreg::bench
