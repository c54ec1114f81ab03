// certificate_radius_for (icp/model_finder.hpp): the certificates' radius cap is 1% of the
// model's diagonal, held, for scans of kWidthCapPoints points and more, to kCertificateWidths times
// the narrow width of the patches where half of the model's area lies. Flat ruled sheets cut into
// thin strips (like the IEA blade's faces) get the strips' cap for a large scan and 1% of the
// diagonal for a small one, and the finder's reset() follows the scan size; coarse strips, and a
// model whose area is mostly one big patch beside many thin ones, keep 1% of the diagonal (the
// area weighting: an unweighted median would be the thin strips').
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "support/hard_surfaces.hpp"

namespace nurbsreg::icp {
namespace {

using engine::Vec3;

// A flat bilinear sheet `length` x `width` in the plane z = height, from x0, cut across its width
// into `strips` Bezier patches (each length x width / strips).
engine::NurbsSurface strip_sheet(double length, double width, int strips, double x0 = 0.0,
                                 double height = 0.0) {
  engine::NurbsSurface s;
  s.name = "strip sheet";
  s.degree_u = 1;
  s.degree_v = 1;
  s.count_u = 2;
  s.count_v = strips + 1;
  s.knots_u = {0, 0, 1, 1};
  s.knots_v = {0};
  for (int k = 0; k <= strips; ++k)
    s.knots_v.push_back(static_cast<double>(k) / strips);
  s.knots_v.push_back(1.0);
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j <= strips; ++j)
      s.control_points.emplace_back(x0 + i * length, width * j / strips, height);
  }
  return s;
}

TEST(CertificateRadius, ThinStripsHoldTheCapToAFewStripWidthsForLargeScans) {
  // 100 x 100 in 400 strips 0.25 wide: 4 x 0.25 = 1.0, below 1% of the diagonal (1.41).
  const engine::PreparedModel thin(test::model_of({strip_sheet(100.0, 100.0, 400)}));
  const double share = 1e-2 * thin.geometry_bounds().box.diagonal();
  EXPECT_NEAR(share, 1e-2 * std::sqrt(2.0) * 100.0, 1e-9);
  EXPECT_NEAR(certificate_radius_for(thin, kWidthCapPoints), kCertificateWidths * 0.25, 1e-9);
  EXPECT_DOUBLE_EQ(certificate_radius_for(thin, kWidthCapPoints - 1), share);
  ModelCorrespondenceFinder finder(thin);
  EXPECT_DOUBLE_EQ(finder.certificate_radius(), share);
  finder.reset(kWidthCapPoints);
  EXPECT_DOUBLE_EQ(finder.certificate_radius(), certificate_radius_for(thin, kWidthCapPoints));
  finder.reset(1000);
  EXPECT_DOUBLE_EQ(finder.certificate_radius(), share);
  // 40 strips 2.5 wide: 1% of the diagonal is the smaller.
  const engine::PreparedModel coarse(test::model_of({strip_sheet(100.0, 100.0, 40)}));
  EXPECT_DOUBLE_EQ(certificate_radius_for(coarse, kWidthCapPoints),
                   1e-2 * coarse.geometry_bounds().box.diagonal());
}

TEST(CertificateRadius, TheWidthIsThatOfThePatchesWhereTheAreaIs) {
  // One 100 x 100 patch beside 400 strips of a 100 x 10 sheet: 401 patches, 400 of them thin,
  // but 10/11 of the area on the big one.
  const engine::PreparedModel mixed(
      test::model_of({strip_sheet(100.0, 100.0, 1), strip_sheet(100.0, 10.0, 400, 200.0, 5.0)}));
  EXPECT_DOUBLE_EQ(certificate_radius_for(mixed, kWidthCapPoints),
                   1e-2 * mixed.geometry_bounds().box.diagonal());
  // A wavy bicubic sheet of 7 x 7 patches about a unit wide: 1% of its diagonal.
  const engine::PreparedModel sheet(test::model_of({test::wavy_sheet(10, 1)}));
  EXPECT_DOUBLE_EQ(certificate_radius_for(sheet, kWidthCapPoints),
                   1e-2 * sheet.geometry_bounds().box.diagonal());
}

}  // namespace
}  // namespace nurbsreg::icp
