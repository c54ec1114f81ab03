#include <tbb/parallel_for.h>

#include <algorithm>
#include <limits>

#include "coarse_detail.hpp"
#include "nurbsreg/engine/cancellation.hpp"

namespace nurbsreg::registration::detail {

std::vector<Match> match_descriptors(const DescriptorMatrix& scan, const ModelDescriptors& model) {
  const Eigen::Index ns = scan.rows();
  const Eigen::Index nm = model.rows();
  std::vector<Match> out;
  if (ns == 0 || nm == 0) return out;
  const Eigen::VectorXf scan_sq = scan.rowwise().squaredNorm();
  const Eigen::VectorXf model_sq = model.rowwise().squaredNorm();
  constexpr Eigen::Index kBlock = 256;
  const Eigen::Index blocks = (ns + kBlock - 1) / kBlock;
  std::vector<std::uint32_t> forward(static_cast<std::size_t>(ns));
  // Per block, each model row's best scan row in the block and its distance.
  std::vector<std::vector<std::pair<float, std::uint32_t>>> backward(
      static_cast<std::size_t>(blocks));
  tbb::parallel_for(Eigen::Index{0}, blocks, [&](Eigen::Index b) {
    const Eigen::Index begin = b * kBlock;
    const Eigen::Index rows = std::min(kBlock, ns - begin);
    // Column-major: a model descriptor's column holds the block's dot products contiguously, so
    // the loops run over the block's rows inside and the model's columns outside (the other
    // order read the product with a stride of a whole column per step). The same distances, the
    // same first minima as a row-by-row scan (strict comparisons in ascending order).
    const Eigen::MatrixXf dot = scan.middleRows(begin, rows) * model.transpose();
    float row_best[kBlock];
    std::uint32_t row_best_j[kBlock];
    std::fill(row_best, row_best + rows, std::numeric_limits<float>::infinity());
    std::fill(row_best_j, row_best_j + rows, 0u);
    const float* scan_sq_block = scan_sq.data() + begin;
    auto& best_scan = backward[static_cast<std::size_t>(b)];
    best_scan.resize(static_cast<std::size_t>(nm));
    for (Eigen::Index j = 0; j < nm; ++j) {
      const float* column = dot.col(j).data();
      const float model_sq_j = model_sq(j);
      std::pair<float, std::uint32_t> best{std::numeric_limits<float>::infinity(), 0};
      for (Eigen::Index r = 0; r < rows; ++r) {
        const float d = scan_sq_block[r] + model_sq_j - 2.0f * column[r];
        if (d < row_best[r]) {
          row_best[r] = d;
          row_best_j[r] = static_cast<std::uint32_t>(j);
        }
        if (d < best.first) best = {d, static_cast<std::uint32_t>(begin + r)};
      }
      best_scan[static_cast<std::size_t>(j)] = best;
    }
    for (Eigen::Index r = 0; r < rows; ++r)
      forward[static_cast<std::size_t>(begin + r)] = row_best_j[r];
  });
  nurbsreg::engine::stop_if_cancelled();
  out.reserve(static_cast<std::size_t>(ns + nm));
  for (Eigen::Index i = 0; i < ns; ++i)
    out.push_back({static_cast<std::uint32_t>(i), forward[static_cast<std::size_t>(i)]});
  for (Eigen::Index j = 0; j < nm; ++j) {
    std::pair<float, std::uint32_t> best{std::numeric_limits<float>::infinity(), 0};
    for (const auto& block : backward) {
      if (block[static_cast<std::size_t>(j)].first < best.first)
        best = block[static_cast<std::size_t>(j)];
    }
    out.push_back({best.second, static_cast<std::uint32_t>(j)});
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace nurbsreg::registration::detail
