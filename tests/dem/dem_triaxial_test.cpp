
#include "dem/repose.hpp"

namespace {

TEST(dem_Repose, ColumnCollapseAngleGrowsWithMu) {
  // docs/soil.md: 1,000 grains in a 5 x 8 cm column; measured 13.2 deg at mu 0.2, 37.3 at 0.5.
  dem::ReposeOptions o;
  o.grains = 1000;
  o.length = 0.05;
  o.friction = 0.2;
  const dem::ReposeResult lo = dem::run_repose(o);
  o.friction = 0.5;
  const dem::ReposeResult hi = dem::run_repose(o);
  std::printf("repose: mu 0.2 %.2f deg, mu 0.5 %.2f deg\n", lo.angle * kDeg, hi.angle * kDeg);
  ASSERT_TRUE(std::isfinite(lo.angle) && std::isfinite(hi.angle));
  EXPECT_TRUE(lo.at_rest && hi.at_rest);
  EXPECT_GE(lo.surface_points, 5);
  EXPECT_GE(hi.surface_points, 5);
  EXPECT_GT(hi.angle * kDeg, lo.angle * kDeg + 10);
  EXPECT_LT(hi.final_height, hi.column_height);  // it did collapse
  EXPECT_LT(lo.final_height, hi.final_height);
  dem::ReposeOptions bad;
  bad.width = 0.01;
  try {
    dem::run_repose(bad);
    FAIL() << "a 1 cm wide box is narrower than 6 diameters";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--width"), std::string::npos) << e.what();
  }
}

}  // namespace
