// Deviation statistics against an independent computation (sorting, the textbook formulas), the
// tolerance band's edges, and the per-face grouping.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <vector>

#include "nurbsreg/inspect/statistics.hpp"

namespace nurbsreg::inspect {
namespace {

// numpy.percentile's default, from a fully sorted copy.
double reference_quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  const double rank = q * (v.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(rank);
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (rank - lo) * (v[hi] - v[lo]);
}

TEST(Statistics, SmallCaseByHand) {
  std::vector<double> d = {0.2, -0.1, 0.05, -0.3, 0.1, 0.0};
  const DeviationStats s = deviation_stats(d, Tolerance{-0.1, 0.1});
  EXPECT_EQ(s.points, 6u);
  // The band's edges are inside: -0.1, 0, 0.05, 0.1.
  EXPECT_EQ(s.inside, 4u);
  EXPECT_EQ(s.below, 1u);
  EXPECT_EQ(s.above, 1u);
  EXPECT_NEAR(s.mean, -0.05 / 6.0, 1e-15);
  const double m = -0.05 / 6.0;
  double ss = 0;
  for (double x : {0.2, -0.1, 0.05, -0.3, 0.1, 0.0})
    ss += (x - m) * (x - m);
  EXPECT_NEAR(s.std, std::sqrt(ss / 5.0), 1e-15);
  EXPECT_NEAR(s.rms, std::sqrt((0.04 + 0.01 + 0.0025 + 0.09 + 0.01) / 6.0), 1e-15);
  EXPECT_EQ(s.min, -0.3);
  EXPECT_EQ(s.max, 0.2);
  // Sorted: -0.3 -0.1 0 0.05 0.1 0.2; rank 0.25 and 4.75.
  EXPECT_NEAR(s.p5, -0.3 + 0.25 * 0.2, 1e-15);
  EXPECT_NEAR(s.p95, 0.1 + 0.75 * 0.1, 1e-15);
  EXPECT_NEAR(s.inside_fraction(), 4.0 / 6.0, 1e-15);
}

TEST(Statistics, RandomValuesMatchTheReference) {
  std::mt19937_64 rng(27);
  std::normal_distribution<double> normal(0.01, 0.05);
  std::vector<double> values(10007);
  for (double& x : values)
    x = normal(rng);
  const std::vector<double> copy = values;
  const Tolerance band{-0.04, 0.07};
  const DeviationStats s = deviation_stats(values, band);
  const double mean = std::accumulate(copy.begin(), copy.end(), 0.0) / copy.size();
  double ss = 0;
  std::size_t inside = 0;
  for (double x : copy) {
    ss += (x - mean) * (x - mean);
    inside += x >= band.lower && x <= band.upper;
  }
  EXPECT_NEAR(s.mean, mean, 1e-15);
  EXPECT_NEAR(s.std, std::sqrt(ss / (copy.size() - 1)), 1e-15);
  EXPECT_EQ(s.inside, inside);
  EXPECT_EQ(s.p5, reference_quantile(copy, 0.05));
  EXPECT_EQ(s.p95, reference_quantile(copy, 0.95));
  EXPECT_EQ(s.min, *std::min_element(copy.begin(), copy.end()));
  EXPECT_EQ(s.max, *std::max_element(copy.begin(), copy.end()));
}

TEST(Statistics, EveryPointInsideIsOneHundredPercent) {
  std::vector<double> d = {-0.05, -0.02, 0.0, 0.03, 0.05};
  const DeviationStats s = deviation_stats(d, Tolerance{-0.05, 0.05});
  EXPECT_EQ(s.inside, 5u);
  EXPECT_EQ(s.inside_fraction(), 1.0);
}

TEST(Statistics, ToleranceEdgesAreInsideAndTheNextDoubleIsNot) {
  const Tolerance band{-0.05, 0.05};
  EXPECT_TRUE(band.inside(0.05));
  EXPECT_TRUE(band.inside(-0.05));
  EXPECT_FALSE(band.inside(std::nextafter(0.05, 1.0)));
  EXPECT_FALSE(band.inside(std::nextafter(-0.05, -1.0)));
  std::vector<double> d = {std::nextafter(0.05, 1.0), 0.05, -0.05, std::nextafter(-0.05, -1.0)};
  const DeviationStats s = deviation_stats(d, band);
  EXPECT_EQ(s.inside, 2u);
  EXPECT_EQ(s.above, 1u);
  EXPECT_EQ(s.below, 1u);
}

TEST(Statistics, OnePointHasZeroSpreadAndEmptyIsNaN) {
  std::vector<double> one = {0.3};
  const DeviationStats s = deviation_stats(one, Tolerance{});
  EXPECT_EQ(s.std, 0.0);
  EXPECT_EQ(s.p5, 0.3);
  EXPECT_EQ(s.p95, 0.3);
  std::vector<double> none;
  const DeviationStats e = deviation_stats(none, Tolerance{});
  EXPECT_EQ(e.points, 0u);
  EXPECT_TRUE(std::isnan(e.mean));
  EXPECT_TRUE(std::isnan(e.inside_fraction()));
}

TEST(Statistics, ToleranceValidation) {
  EXPECT_FALSE(Tolerance({-0.1, 0.2}).validate());
  EXPECT_TRUE(Tolerance({0.1, -0.1}).validate());
  EXPECT_TRUE(Tolerance({0.1, 0.1}).validate());
  EXPECT_TRUE(Tolerance({NAN, 0.1}).validate());
}

TEST(Statistics, PerFaceGroupingAndHistogram) {
  engine::Model model;
  model.surfaces.resize(3);
  model.surfaces[0].name = "a";
  model.surfaces[1].name = "b";
  model.surfaces[2].name = "never measured";
  PointDeviations dev;
  const std::vector<std::pair<int, double>> points = {
      {1, 0.2}, {0, -0.05}, {1, 0.0}, {0, 0.01}, {1, -0.4}};
  for (const auto& [face, d] : points) {
    dev.points.emplace_back(0, 0, 0);
    dev.signed_distance.push_back(d);
    dev.face.push_back(face);
    dev.u.push_back(0);
    dev.v.push_back(0);
    dev.source_index.push_back(dev.source_index.size());
  }
  dev.skipped_nonfinite = 2;
  const InspectionStatistics st =
      compute_statistics(dev, model, Tolerance{-0.1, 0.1}, -0.3, 0.3, 6);
  ASSERT_EQ(st.faces.size(), 3u);
  EXPECT_EQ(st.faces[0].stats.points, 2u);
  EXPECT_NEAR(st.faces[0].stats.mean, -0.02, 1e-15);
  EXPECT_EQ(st.faces[0].stats.inside, 2u);
  EXPECT_EQ(st.faces[1].stats.points, 3u);
  EXPECT_EQ(st.faces[1].stats.min, -0.4);
  EXPECT_EQ(st.faces[1].stats.above, 1u);
  EXPECT_EQ(st.faces[1].name, "b");
  EXPECT_EQ(st.faces[2].stats.points, 0u);
  EXPECT_TRUE(std::isnan(st.faces[2].stats.mean));
  EXPECT_EQ(st.overall.points, 5u);
  EXPECT_EQ(st.skipped_nonfinite, 2u);
  // Bins of 0.1 over [-0.3, 0.3): -0.05 and 0.01 and 0.0 and 0.2; -0.4 under.
  EXPECT_EQ(st.histogram.under, 1u);
  EXPECT_EQ(st.histogram.over, 0u);
  const std::vector<std::size_t> expected = {0, 0, 1, 2, 0, 1};
  EXPECT_EQ(st.histogram.counts, expected);
}

}  // namespace
}  // namespace nurbsreg::inspect
