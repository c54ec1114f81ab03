// registration::far_from_model_note: `project`'s warning for points that mostly lie farther from
// the model than its own size (a scan still in the scanner's frame, or of another part).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "nurbsreg/registration/scan_size.hpp"

namespace nurbsreg::registration {
namespace {

// `far` of `n` distances are 5 (five model sizes), the rest 0.01, interleaved.
std::vector<double> distances(std::size_t n, std::size_t far) {
  std::vector<double> d(n, 0.01);
  for (std::size_t i = 0; i < far; ++i)
    d[(i * 7919) % n] = 5.0;
  return d;
}

TEST(FarFromModel, HalfOfThePointsNearKeepItQuiet) {
  // Clutter and outliers up to just under half of the points: the median is near.
  EXPECT_FALSE(far_from_model_note(distances(1001, 500), 1.0, "mm"));
  const auto note = far_from_model_note(distances(1001, 501), 1.0, "mm");
  ASSERT_TRUE(note);
  EXPECT_NE(note->find("half of the points lie 5 mm or more from the model"), std::string::npos)
      << *note;
  EXPECT_NE(note->find("5.0 times its size"), std::string::npos) << *note;
  EXPECT_NE(note->find("is the scan in the model's frame?"), std::string::npos) << *note;
}

TEST(FarFromModel, TheThresholdIsTheModelsSize) {
  const std::vector<double> d(10, 2.0);
  EXPECT_FALSE(far_from_model_note(d, 2.0, "mm"));  // not beyond the model's size
  EXPECT_TRUE(far_from_model_note(d, 1.999, "mm"));
  EXPECT_FALSE(far_from_model_note(d, 0.0, "mm"));  // a model with no size says nothing
  EXPECT_FALSE(far_from_model_note({}, 1.0, "mm"));
}

TEST(FarFromModel, SkippedPointsDoNotCount) {
  // Non-finite distances (points skipped as NaN or infinite) are left out of the median: three
  // near points against two far ones stay quiet, whatever the skipped ones would have said.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> d = {nan, 0.1, nan, 9.0, 0.1, nan, 9.0, 0.1, nan, nan};
  EXPECT_FALSE(far_from_model_note(d, 1.0, "mm"));
  const std::vector<double> all_skipped(5, nan);
  EXPECT_FALSE(far_from_model_note(all_skipped, 1.0, "mm"));
}

TEST(FarFromModel, LargeFramesAreJudgedOnAnEvenSample) {
  // 300,000 points (more than kFarSample), 4 in 7 far: the sampled median finds them; 3 in 7
  // far does not warn.
  std::vector<double> d(300000);
  static_assert(300000 > kFarSample);
  for (std::size_t i = 0; i < d.size(); ++i)
    d[i] = (i % 7 < 4) ? 3.0 : 0.01;
  EXPECT_TRUE(far_from_model_note(d, 1.0, "mm"));
  for (std::size_t i = 0; i < d.size(); ++i)
    d[i] = (i % 7 < 3) ? 3.0 : 0.01;
  EXPECT_FALSE(far_from_model_note(d, 1.0, "mm"));
}

}  // namespace
}  // namespace nurbsreg::registration
