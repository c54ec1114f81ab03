// The failed global alignment's diagnosis of a scan that no pose from anywhere could place
// (registration/src/scan_shape.cpp): flat scans and scans along a line are named with their
// numbers; curved scans, however thin, are not.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "../../registration/src/scan_shape.hpp"

namespace nurbsreg::registration::detail {
namespace {

using engine::Vec3;

// n points of the square [0, side]^2 with Gaussian noise off it, turned and moved far from the
// origin (the spread must come from the points about their mean, not about the origin).
std::vector<Vec3> square(std::size_t n, double side, double noise) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, side);
  std::normal_distribution<double> g(0.0, noise);
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(0.7, Vec3(1.0, 2.0, 3.0).normalized()).toRotationMatrix();
  std::vector<Vec3> out;
  for (std::size_t i = 0; i < n; ++i)
    out.push_back(turn * Vec3(u(rng), u(rng), noise > 0.0 ? g(rng) : 0.0) + Vec3(1e4, -2e4, 5e3));
  return out;
}

// The number right after `prefix` in `text` (NaN when the prefix is missing).
double number_after(const std::string& text, const std::string& prefix) {
  const std::size_t at = text.find(prefix);
  if (at == std::string::npos) return std::numeric_limits<double>::quiet_NaN();
  return std::stod(text.substr(at + prefix.size()));
}

TEST(ScanShape, AFlatScanIsNamedWithItsSpreadAndSize) {
  const auto note = flat_scan_note(square(20000, 80.0, 0.1), 0.1);
  ASSERT_TRUE(note);
  EXPECT_NE(note->find("the scan is flat"), std::string::npos) << *note;
  EXPECT_NEAR(number_after(*note, "its points lie "), 0.1, 0.005) << *note;
  EXPECT_NEAR(number_after(*note, "about "), 80.0, 2.0) << *note;
  EXPECT_NE(note->find("every flat face"), std::string::npos) << *note;
}

TEST(ScanShape, ANoiseFreeFlatScanIsFlat) {
  const auto note = flat_scan_note(square(2000, 10.0, 0.0), 0.0);
  ASSERT_TRUE(note);
  EXPECT_NE(note->find("the scan is flat"), std::string::npos) << *note;
}

TEST(ScanShape, AScanAlongALineIsNamedALine) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 50.0);
  std::normal_distribution<double> g(0.0, 0.05);
  std::vector<Vec3> line;
  for (int i = 0; i < 5000; ++i)
    line.push_back(Vec3(u(rng), g(rng), g(rng)));
  const auto note = flat_scan_note(line, 0.05);
  ASSERT_TRUE(note);
  EXPECT_NE(note->find("the scan is a line"), std::string::npos) << *note;
  EXPECT_NEAR(number_after(*note, "about "), 50.0, 2.0) << *note;
}

// A shallow cap of a sphere (radius 500, 80 x 80 across: its corners 3.2 below its centre) with
// the flat square's noise: its points lie about 0.68 rms off their plane, nearly seven times the
// noise. Not flat: its curvature fixes a pose in it. Were the scan's noise 0.4, the same sag
// would be within twice the noise: flat.
TEST(ScanShape, AShallowCurvedScanIsNotFlat) {
  std::vector<Vec3> cap;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-40.0, 40.0);
  std::normal_distribution<double> g(0.0, 0.1);
  const double r = 500.0;
  for (int i = 0; i < 20000; ++i) {
    const double x = u(rng), y = u(rng);
    cap.push_back(Vec3(x, y, std::sqrt(r * r - x * x - y * y) - r + g(rng)));
  }
  EXPECT_FALSE(flat_scan_note(cap, 0.1)) << *flat_scan_note(cap, 0.1);
  EXPECT_TRUE(flat_scan_note(cap, 0.4));
}

TEST(ScanShape, FewerThanThreePointsSayNothing) {
  EXPECT_FALSE(flat_scan_note({}, 0.0));
  const std::vector<Vec3> two = {Vec3(0, 0, 0), Vec3(1, 0, 0)};
  EXPECT_FALSE(flat_scan_note(two, 0.0));
}

}  // namespace
}  // namespace nurbsreg::registration::detail
