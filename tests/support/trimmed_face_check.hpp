#pragma once
// Is a projection answer a point of the model's trimmed face? For tests and benchmarks: it uses
// the model's own data (surface evaluation, TrimRegion::contains, the 3-D trim edges), none of
// the projection code. A foot is valid when it is S(u, v) at the reported (u, v) with (u, v) in
// the trimmed region, or when it lies on one of the face's boundary edges. Built lazily per
// surface; not thread-safe.

#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <vector>

#include "nurbsreg/engine/model.hpp"
#include "nurbsreg/engine/trim_region.hpp"
#include "support/golden_section.hpp"

namespace nurbsreg::test {

struct FootCheck {
  bool on_surface = false;   // |S(u, v) - foot| <= tol
  bool in_region = false;    // (u, v) in the trimmed region (true for untrimmed surfaces)
  double edge_distance = 0;  // distance from the foot to the face's nearest trim edge (inf if none)
  bool valid(double tol) const { return (on_surface && in_region) || edge_distance <= tol; }
};

class TrimmedFaceCheck {
 public:
  explicit TrimmedFaceCheck(const engine::Model& model) : model_(model) {}

  FootCheck check(int surface, double u, double v, const engine::Vec3& foot, double tol) {
    const engine::NurbsSurface& s = model_.surfaces.at(surface);
    const Prepared& face = prepared(surface);
    FootCheck out;
    out.on_surface = (s.evaluate(u, v) - foot).norm() <= tol;
    const engine::ParamInterval du = s.domain_u(), dv = s.domain_v();
    const bool in_domain = u >= du.lo && u <= du.hi && v >= dv.lo && v <= dv.hi;
    out.in_region = in_domain && (!s.is_trimmed() || face.region->contains(u, v));
    out.edge_distance = edge_distance(surface, foot);
    return out;
  }

  // Distance from q to the nearest trim edge of a surface (infinity when it has none).
  double edge_distance(int surface, const engine::Vec3& q) {
    double best = std::numeric_limits<double>::infinity();
    for (const Edge& e : prepared(surface).edges)
      best = std::min(best, e.distance(q));
    return best;
  }

  // How much worse than the brute-force reference (cad_reference.hpp) an exact projector may be
  // at that reference foot without being wrong: 0, except where the reference's foot is on a
  // face boundary that the file defines twice (its 3-D edge and the face's trim curve S(uv(t))
  // differ by the file's tolerance) and the model took the other one. Then the model's own edge
  // is at most its distance from the reference foot away (triangle inequality). Surfaces must be
  // the file's faces in order (no skipped face).
  template <class Reference, class Foot>
  double boundary_allowance(const Reference& reference, const Foot& ref) {
    double allowed = 0;
    if (ref.face >= 0 && ref.stopped_by_boundary) {
      allowed = edge_distance(ref.face, ref.foot);
    } else if (ref.edge >= 0) {
      allowed = std::numeric_limits<double>::infinity();
      for (const int f : reference.edge_faces(ref.edge))
        allowed = std::min(allowed, edge_distance(f, ref.foot));
    }
    return std::isfinite(allowed) ? allowed : 0.0;
  }

 private:
  struct Edge {
    engine::NurbsCurve curve;
    std::vector<engine::Vec3> samples;
    double distance(const engine::Vec3& q) const {
      const int n = static_cast<int>(samples.size()) - 1;
      int best = 0;
      double bd = HUGE_VAL;
      for (int k = 0; k <= n; ++k) {
        const double d = (samples[k] - q).norm();
        if (d < bd) bd = d, best = k;
      }
      // Golden section between the neighbours of the best sample.
      const engine::ParamInterval dom = curve.domain();
      double a = dom.to_parent(static_cast<double>(std::max(best - 1, 0)) / n);
      double b = dom.to_parent(static_cast<double>(std::min(best + 1, n)) / n);
      auto f = [&](double t) { return (curve.evaluate(t) - q).norm(); };
      return std::min(bd, golden_section_minimum(f, a, b, 80));
    }
  };
  struct Prepared {
    std::unique_ptr<engine::TrimRegion> region;
    std::vector<Edge> edges;
  };

  const Prepared& prepared(int surface) {
    auto it = cache_.find(surface);
    if (it != cache_.end()) return it->second;
    const engine::NurbsSurface& s = model_.surfaces[surface];
    Prepared p;
    if (s.is_trimmed()) {
      p.region = std::make_unique<engine::TrimRegion>(s);
      for (engine::TrimEdge& te : engine::trim_edges(s)) {
        Edge e{std::move(te.edge), {}};
        const engine::ParamInterval dom = e.curve.domain();
        const int n = 2000;
        for (int k = 0; k <= n; ++k)
          e.samples.push_back(e.curve.evaluate(dom.to_parent(1.0 * k / n)));
        p.edges.push_back(std::move(e));
      }
    }
    return cache_.emplace(surface, std::move(p)).first->second;
  }

  const engine::Model& model_;
  std::map<int, Prepared> cache_;
};

}  // namespace nurbsreg::test
