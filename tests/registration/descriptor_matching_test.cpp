// The coarse stage's descriptor matches (correspondences.cpp, match_descriptors): every scan
// descriptor's nearest model descriptor and every model descriptor's nearest scan descriptor,
// as the union of those pairs, sorted. Checked against a plain scan over all pairs, row by row,
// with the distance as the matcher defines it, |s|^2 + |m|^2 - 2 s.m in float with every sum in
// index order (so the same bits whichever vector width the matcher runs at): the first minimum
// wins ties, on descriptors with exact duplicates (ties), more scan rows than one block of the
// matcher, and a model count that leaves its last panel part empty.
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <random>
#include <vector>

#include "../../registration/src/coarse_detail.hpp"

namespace nurbsreg::registration::detail {
namespace {

DescriptorMatrix random_descriptors(std::mt19937_64& rng, int rows, int cols) {
  std::uniform_real_distribution<float> bin(0.0f, 1.0f);
  DescriptorMatrix d(rows, cols);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      d(r, c) = bin(rng);
  return d;
}

float sum_of_products(const float* a, const float* b, int n) {
  float s = 0.0f;
  for (int k = 0; k < n; ++k)
    s += a[k] * b[k];
  return s;
}

std::vector<Match> reference_matches(const DescriptorMatrix& scan, const DescriptorMatrix& model) {
  const int n = static_cast<int>(scan.cols());
  std::vector<float> distance(static_cast<std::size_t>(scan.rows() * model.rows()));
  for (Eigen::Index i = 0; i < scan.rows(); ++i) {
    const float* s = scan.row(i).data();
    for (Eigen::Index j = 0; j < model.rows(); ++j) {
      const float* m = model.row(j).data();
      distance[static_cast<std::size_t>(i * model.rows() + j)] =
          (sum_of_products(s, s, n) + sum_of_products(m, m, n)) - 2.0f * sum_of_products(s, m, n);
    }
  }
  const auto at = [&](Eigen::Index i, Eigen::Index j) {
    return distance[static_cast<std::size_t>(i * model.rows() + j)];
  };
  std::vector<Match> out;
  for (Eigen::Index i = 0; i < scan.rows(); ++i) {
    Eigen::Index best = 0;
    for (Eigen::Index j = 1; j < model.rows(); ++j)
      if (at(i, j) < at(i, best)) best = j;
    out.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(best)});
  }
  for (Eigen::Index j = 0; j < model.rows(); ++j) {
    Eigen::Index best = 0;
    for (Eigen::Index i = 1; i < scan.rows(); ++i)
      if (at(i, j) < at(best, j)) best = i;
    out.push_back({static_cast<std::uint32_t>(best), static_cast<std::uint32_t>(j)});
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

TEST(DescriptorMatching, MutualNearestPairsAsAPlainScanFindsThem) {
  std::mt19937_64 rng(25);
  DescriptorMatrix scan = random_descriptors(rng, 700, kDescriptorSize);
  DescriptorMatrix model = random_descriptors(rng, 453, kDescriptorSize);
  // Ties: duplicated model rows, scan rows equal to model rows, duplicated scan rows within one
  // block of the matcher and across blocks. The first of equals wins on both sides.
  model.row(17) = model.row(3);
  model.row(400) = model.row(3);
  scan.row(5) = model.row(100);
  model.row(200) = model.row(100);  // scan row 5's nearest twice: row 100 first
  // Model rows 3, 17 and 400 are equal, and their nearest scan row is there four times: row 10
  // first, then 11 in the same block and 300 and 600 in later ones. The scan rows' own nearest
  // is row 3 (the first model row of equals), so only the model side names 17 and 400.
  scan.row(10) = model.row(3);
  scan.row(11) = scan.row(10);
  scan.row(300) = scan.row(10);
  scan.row(600) = scan.row(10);
  const std::vector<Match> matches = match_descriptors(scan, model);
  EXPECT_EQ(matches, reference_matches(scan, model));
  // The exact duplicates found their twins, the first of equals.
  EXPECT_NE(std::find(matches.begin(), matches.end(), Match{5, 100}), matches.end());
  EXPECT_NE(std::find(matches.begin(), matches.end(), Match{10, 3}), matches.end());
  EXPECT_NE(std::find(matches.begin(), matches.end(), Match{10, 17}), matches.end());
  EXPECT_NE(std::find(matches.begin(), matches.end(), Match{10, 400}), matches.end());
}

}  // namespace
}  // namespace nurbsreg::registration::detail
