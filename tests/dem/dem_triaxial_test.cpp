// The true-triaxial test (docs/soil.md): the servo holds the confining stress within 2 % on a
// small sample; the friction angle grows with the grains' friction; the Mohr-Coulomb fit
// recovers phi and c from the closed form; bad options refused by name.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "dem/repose.hpp"
#include "dem/triaxial.hpp"

namespace {

constexpr double kDeg = 180 / M_PI;

dem::TriaxialResult small(double mu) {
  dem::TriaxialOptions o;
  o.grains = 400;
  o.friction = mu;
  o.confining = 2000;
  o.max_strain = 0.04;
  const dem::TriaxialResult r = dem::run_triaxial(o);
  std::printf("mu %.2f: packing %.4f, peak ratio %.3f at %.3f, phi_peak %.2f deg, servo error %.2f %%\n",
              mu, r.initial_fraction, r.peak_ratio, r.peak_strain, r.peak_phi * kDeg, 100 * r.servo_error);
  return r;
}

TEST(dem_Triaxial, ServoHoldsTheConfiningStressAndPhiGrowsWithMu) {
  const dem::TriaxialResult lo = small(0.1), hi = small(0.5);
  for (const dem::TriaxialResult* r : {&lo, &hi}) {
    ASSERT_GE(r->curve.size(), 39u);
    EXPECT_LT(r->servo_error, 0.02);
    for (const dem::TriaxialSample& p : r->curve) {
      EXPECT_NEAR(p.sigma_x, 2000, 40) << p.axial_strain;
      EXPECT_NEAR(p.sigma_y, 2000, 40) << p.axial_strain;
    }
    EXPECT_GT(r->initial_fraction, 0.5);  // a packing, not a gas
    EXPECT_NEAR(r->curve.back().axial_strain, 0.04, 0.002);
  }
  // Axial stress above the confining one from the first samples on.
  EXPECT_GT(lo.curve[5].sigma1, 2000 * 1.2);
  EXPECT_GT(hi.peak_phi * kDeg, lo.peak_phi * kDeg + 10);
  EXPECT_GT(lo.peak_phi * kDeg, 10);
}

TEST(dem_Triaxial, MohrCoulombFitRecoversTheClosedForm) {
  // sigma1 = sigma3 K_p + 2 c sqrt(K_p), K_p = tan^2(45 + phi/2): phi 35 deg, c 500 Pa.
  const double phi = 35 / kDeg, c = 500, kp = std::pow(std::tan(M_PI / 4 + phi / 2), 2);
  std::vector<double> s3{1000, 2000, 4000}, s1;
  for (double s : s3) s1.push_back(s * kp + 2 * c * std::sqrt(kp));
  const dem::MohrCoulomb m = dem::mohr_coulomb_fit(s3, s1);
  EXPECT_NEAR(m.phi * kDeg, 35, 1e-9);
  EXPECT_NEAR(m.cohesion, 500, 1e-6);
  EXPECT_THROW(dem::mohr_coulomb_fit({1000}, {3000}), std::invalid_argument);
}

TEST(dem_Triaxial, BadOptionsAreRefusedByName) {
  auto message = [](auto change) {
    dem::TriaxialOptions o;
    change(o);
    try {
      dem::validate(o);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message([](dem::TriaxialOptions&) {}), "accepted");
  EXPECT_NE(message([](dem::TriaxialOptions& o) { o.grains = 10; }).find("--grains"), std::string::npos);
  EXPECT_NE(message([](dem::TriaxialOptions& o) { o.friction = -1; }).find("--mu"), std::string::npos);
  EXPECT_NE(message([](dem::TriaxialOptions& o) { o.confining = 0; }).find("--pressures"), std::string::npos);
  EXPECT_NE(message([](dem::TriaxialOptions& o) { o.confining = 1e6; }).find("raise --stiffness"), std::string::npos);
  EXPECT_NE(message([](dem::TriaxialOptions& o) { o.strain_rate = NAN; }).find("--rate"), std::string::npos);
  EXPECT_NE(message([](dem::TriaxialOptions& o) { o.max_strain = 0.9; }).find("--max-strain"), std::string::npos);
  EXPECT_NE(message([](dem::TriaxialOptions& o) { o.restitution = 0; }).find("--restitution"), std::string::npos);
}

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
