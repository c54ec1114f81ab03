#pragma once
// What the driver needs from every projection method it measures, nurbsreg included: a batch
// call that fills one distance per point. Each implementation parallelises with
// tbb::parallel_for in the caller's task arena (the driver owns the thread count) and keeps
// one projector object per thread, built before timing starts.

#include <limits>
#include <memory>
#include <span>
#include <string>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::bench {

// Distance reported for a point the method returned nothing for.
inline constexpr double kNoResult = std::numeric_limits<double>::infinity();

class Peer {
 public:
  virtual ~Peer() = default;
  // Column label, e.g. "OCCT Extrema Grad".
  virtual std::string name() const = 0;
  // Approximate methods report their error, exact ones their failures.
  virtual bool exact() const { return true; }
  // Builds every per-thread projector for up to `max_threads` threads (not timed as
  // projection: the driver reports it as preparation).
  virtual void prepare_threads(int max_threads) = 0;
  // distance[i] = the method's distance from points[i] to the model, kNoResult if none.
  virtual void project(std::span<const engine::Vec3> points, std::span<double> distance) = 0;

  // Warm start (ICP): remember the feet of `previous` as hints for the next project_warm.
  virtual bool supports_warm() const { return false; }
  virtual void set_hints_from(std::span<const engine::Vec3> /*previous*/) {}
  virtual void project_warm(std::span<const engine::Vec3> /*points*/,
                            std::span<double> /*distance*/) {}
  // Certified warm starts (nurbsreg: engine::WarmCertificate): when on, every projection also
  // makes certificates and the hints carry them, as ICP's iterations do.
  virtual bool supports_certify() const { return false; }
  virtual void set_certify(bool /*on*/) {}
};

// Factories; each is defined only when its library was found (see CMakeLists.txt), and throws
// std::runtime_error if the converted model does not evaluate like ours.
#ifdef NURBSREG_BENCH_HAVE_OCCT
// GeomAPI_ProjectPointOnSurf with Extrema_ExtAlgo_Grad (tree == false, OCCT's default) or
// Extrema_ExtAlgo_Tree.
std::unique_ptr<Peer> make_occt_peer(const engine::Model& model, bool tree);
#endif
#ifdef NURBSREG_BENCH_HAVE_SISL
// SISL s1954 (global closest point), geometric resolution `epsge` (model units).
std::unique_ptr<Peer> make_sisl_peer(const engine::Model& model, double epsge);
#endif
#ifdef NURBSREG_BENCH_HAVE_FLANN
// Nearest of `samples` area-uniform surface samples, FLANN single kd-tree (exact search).
std::unique_ptr<Peer> make_flann_peer(const engine::Model& model, std::size_t samples);
#endif
#ifdef NURBSREG_BENCH_HAVE_ENGINE_PROJECTION
// nurbsreg's PreparedModel + Projector (exact, cold and warm-started).
std::unique_ptr<Peer> make_nurbsreg_peer(const engine::Model& model);
#endif

}  // namespace nurbsreg::bench
