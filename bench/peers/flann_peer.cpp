// FLANN peer: what a point-cloud pipeline does without a CAD kernel. The model is replaced by a
// dense area-uniform sampling and every point takes the nearest sample, found exactly by
// FLANN's single kd-tree. The answer is approximate by construction (the distance to the
// nearest sample, never below the true distance): the driver reports its error.

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <flann/flann.hpp>

#include <cmath>
#include <vector>

#include "nurbsreg/engine/sampling.hpp"
#include "peer.hpp"

namespace nurbsreg::bench {
namespace {

using engine::Vec3;

class FlannPeer final : public Peer {
 public:
  FlannPeer(const engine::Model& model, std::size_t count) : count_(count) {
    const auto samples = engine::sample_surfaces(model, count, 0xf1a77);
    data_.resize(samples.size() * 3);
    for (std::size_t k = 0; k < samples.size(); ++k) {
      for (int c = 0; c < 3; ++c)
        data_[3 * k + c] = samples[k].point[c];
    }
    index_ = std::make_unique<flann::Index<flann::L2_Simple<double>>>(
        flann::Matrix<double>(data_.data(), samples.size(), 3), flann::KDTreeSingleIndexParams(10));
    index_->buildIndex();
  }

  std::string name() const override {
    return "FLANN kd-tree, " + std::to_string(count_ / 1000) + "k samples";
  }
  bool exact() const override { return false; }
  void prepare_threads(int) override {}

  void project(std::span<const Vec3> points, std::span<double> distance) override {
    // Eigen::Vector3d is three packed doubles, so a span of them is an N x 3 row-major matrix.
    static_assert(sizeof(Vec3) == 3 * sizeof(double));
    const flann::SearchParams params(flann::FLANN_CHECKS_UNLIMITED, 0.0f, false);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                        const std::size_t n = range.size();
                        // One allocation per block of points (not per point), as a caller batching
                        // queries would do.
                        std::vector<std::size_t> indices(n);
                        std::vector<double> squared(n);
                        const flann::Matrix<double> queries(
                            const_cast<double*>(points[range.begin()].data()), n, 3);
                        flann::Matrix<std::size_t> index_matrix(indices.data(), n, 1);
                        flann::Matrix<double> distance_matrix(squared.data(), n, 1);
                        index_->knnSearch(queries, index_matrix, distance_matrix, 1, params);
                        for (std::size_t k = 0; k < n; ++k)
                          distance[range.begin() + k] = std::sqrt(squared[k]);
                      });
  }

 private:
  std::size_t count_;
  std::vector<double> data_;
  std::unique_ptr<flann::Index<flann::L2_Simple<double>>> index_;
};

}  // namespace

std::unique_ptr<Peer> make_flann_peer(const engine::Model& model, std::size_t samples) {
  return std::make_unique<FlannPeer>(model, samples);
}

}  // namespace nurbsreg::bench
