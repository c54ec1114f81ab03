// The colour map: one colour for the band, graded beyond it, saturated beyond the limits.
#include <gtest/gtest.h>

#include "nurbsreg/inspect/colour_map.hpp"

namespace nurbsreg::inspect {
namespace {

TEST(ColourMap, BandIsOneColourAndTheEndsSaturate) {
  for (const ColourScheme scheme : {ColourScheme::metrology, ColourScheme::blue_red}) {
    const ColourScale s = ColourScale::around(Tolerance{-0.05, 0.1}, scheme);
    EXPECT_FALSE(s.validate());
    EXPECT_EQ(s.colour(-0.05), s.band_colour());
    EXPECT_EQ(s.colour(0.0), s.band_colour());
    EXPECT_EQ(s.colour(0.1), s.band_colour());
    EXPECT_NE(s.colour(0.1001), s.band_colour());
    EXPECT_NE(s.colour(-0.0501), s.band_colour());
    EXPECT_EQ(s.colour(s.upper_limit), s.colour(s.upper_limit * 50));
    EXPECT_EQ(s.colour(s.lower_limit), s.colour(s.lower_limit * 50));
    EXPECT_NE(s.colour(0.5 * (s.band.upper + s.upper_limit)), s.colour(s.upper_limit));
    EXPECT_NE(s.colour(s.upper_limit), s.colour(s.lower_limit));
  }
}

TEST(ColourMap, DefaultLimitsAndValidation) {
  const ColourScale s = ColourScale::around(Tolerance{-0.1, 0.1}, ColourScheme::metrology);
  EXPECT_DOUBLE_EQ(s.lower_limit, -0.3);
  EXPECT_DOUBLE_EQ(s.upper_limit, 0.3);
  ColourScale bad = s;
  bad.upper_limit = 0.1;
  EXPECT_TRUE(bad.validate());
  bad = s;
  bad.lower_limit = -0.05;
  EXPECT_TRUE(bad.validate());
  EXPECT_EQ(parse_colour_scheme("blue-red"), ColourScheme::blue_red);
  EXPECT_FALSE(parse_colour_scheme("rainbow"));
}

}  // namespace
}  // namespace nurbsreg::inspect
