// The nurbsreg column: PreparedModel + Projector, the engine's public batch API, used exactly as
// an application would (prepare once, project frames, warm-start from the previous frame, with
// or without certificates).

#include <algorithm>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "peer.hpp"

namespace nurbsreg::bench {
namespace {

using engine::Vec3;

class NurbsregPeer final : public Peer {
 public:
  explicit NurbsregPeer(const engine::Model& model) : prepared_(model), projector_(prepared_) {}

  std::string name() const override { return "nurbsreg"; }

  void prepare_threads(int) override {
    // The reach bounds a warm frame builds on demand: built here, so they count in "prep s"
    // and the cold rows use them too (as an ICP run's frames after its first do).
    prepared_.prepare_reach_bounds();
    // The projector's per-thread scratch grows during its first frame and is reused after:
    // one small frame here so timing starts from the steady state an application sees.
    const auto& box = prepared_.bounds();
    std::vector<Vec3> warmup(4096);
    for (std::size_t i = 0; i < warmup.size(); ++i) {
      const double t = static_cast<double>(i) / warmup.size();
      warmup[i] = box.lo + (box.hi - box.lo).cwiseProduct(Vec3(t, 1.0 - t, (i % 7) / 6.0));
    }
    projector_.project(engine::PointView::of(warmup), options_, results_);
  }

  void project(std::span<const Vec3> points, std::span<double> distance) override {
    projector_.project(engine::PointView::of(points), options_, results_);
    copy_distances(distance);
  }

  bool supports_warm() const override { return true; }
  bool supports_certify() const override { return true; }
  void set_certify(bool on) override { options_.certify = on; }

  void set_hints_from(std::span<const Vec3> previous) override {
    projector_.project(engine::PointView::of(previous), options_, results_);
    hints_.resize(previous.size());
    for (std::size_t i = 0; i < previous.size(); ++i)
      hints_[i] = results_.hint(i);
  }

  void project_warm(std::span<const Vec3> points, std::span<double> distance) override {
    // Uses the hints' certificates but makes none, as ICP's full-resolution passes do
    // (icp::ModelCorrespondenceFinder): a point whose certificate no longer holds is projected
    // with the plain warm start.
    engine::ProjectionOptions warm = options_;
    warm.certify = false;
    projector_.project(engine::PointView::of(points), warm, results_,
                       std::span<const engine::ProjectionHint>(hints_).first(points.size()));
    copy_distances(distance);
  }

 private:
  void copy_distances(std::span<double> distance) const {
    for (std::size_t i = 0; i < distance.size(); ++i) {
      distance[i] =
          results_.status[i] == engine::ProjectionStatus::ok ? results_.distance[i] : kNoResult;
    }
  }

  engine::PreparedModel prepared_;
  engine::Projector projector_;
  engine::ProjectionOptions options_;
  engine::ProjectionResults results_;
  std::vector<engine::ProjectionHint> hints_;
};

}  // namespace

std::unique_ptr<Peer> make_nurbsreg_peer(const engine::Model& model) {
  return std::make_unique<NurbsregPeer>(model);
}

}  // namespace nurbsreg::bench
