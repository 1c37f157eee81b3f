// Reece's earthmoving equation from the Coulomb trial wedge (docs/soil.md): the smooth vertical
// blade gives Rankine's K_p / 2 exactly; a rough vertical blade gives Coulomb's passive
// coefficient (closed form, NAVFAC DM 7.02; table value 4.977 for phi 30, delta 15, Das); the
// equilibrium solved as a linear system equals McKyes' closed form at every failure angle.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "dem/earthmoving.hpp"

namespace {

constexpr double kDeg = M_PI / 180;

TEST(dem_Earthmoving, SmoothVerticalBladeIsRankine) {
  for (double phi : {20.0, 25.0, 30.0, 35.0, 40.0, 45.0}) {
    const dem::WedgeResult r = dem::passive_wedge(90 * kDeg, phi * kDeg, 0);
    const double kp = std::pow(std::tan((45 + phi / 2) * kDeg), 2);
    EXPECT_NEAR(r.n_gamma, kp / 2, 1e-10 * kp) << "phi " << phi;
    EXPECT_NEAR(r.beta, (45 - phi / 2) * kDeg, 1e-6) << "phi " << phi;  // Rankine's plane
    EXPECT_NEAR(r.horizontal, kp / 2, 1e-10 * kp);
    EXPECT_NEAR(r.vertical, 0, 1e-12);
    EXPECT_DOUBLE_EQ(dem::rankine_kp(phi * kDeg), kp);
  }
  EXPECT_NEAR(dem::rankine_kp(30 * kDeg), 3.0, 1e-12);  // tan^2 60
}

TEST(dem_Earthmoving, RoughVerticalBladeIsCoulombsPassiveCoefficient) {
  // Table value: phi 30, delta 15, vertical wall, level backfill: K_p = 4.977 (Das, Principles
  // of Geotechnical Engineering, table of Coulomb's K_p).
  EXPECT_NEAR(dem::coulomb_kp(30 * kDeg, 15 * kDeg, 0), 4.977, 1e-3);
  const dem::WedgeResult r = dem::passive_wedge(90 * kDeg, 30 * kDeg, 15 * kDeg);
  EXPECT_NEAR(2 * r.n_gamma, 4.977, 2e-3);
  for (double phi : {25.0, 30.0, 35.0, 40.0})
    for (double frac : {0.0, 1.0 / 3, 0.5, 2.0 / 3}) {
      const double delta = frac * phi;
      const dem::WedgeResult w = dem::passive_wedge(90 * kDeg, phi * kDeg, delta * kDeg);
      EXPECT_NEAR(2 * w.n_gamma, dem::coulomb_kp(phi * kDeg, delta * kDeg, 0), 1e-9 * w.n_gamma)
          << "phi " << phi << " delta " << delta;
      EXPECT_NEAR(w.horizontal, w.n_gamma * std::cos(delta * kDeg), 1e-12);
    }
}

TEST(dem_Earthmoving, InclinedBladeIsCoulombsWallLeaningBack) {
  // A blade at rake alpha is Coulomb's wall turned 90 - alpha from the vertical.
  for (double alpha : {45.0, 60.0, 75.0})
    for (double phi : {30.0, 40.0})
      for (double delta : {0.0, 0.5 * phi}) {
        const dem::WedgeResult w = dem::passive_wedge(alpha * kDeg, phi * kDeg, delta * kDeg);
        const double kp = dem::coulomb_kp(phi * kDeg, delta * kDeg, (90 - alpha) * kDeg);
        EXPECT_NEAR(2 * w.n_gamma, kp, 1e-8 * kp) << alpha << " " << phi << " " << delta;
      }
}

TEST(dem_Earthmoving, LinearSystemEqualsMcKyesClosedForm) {
  for (double alpha : {30.0, 60.0, 90.0})
    for (double beta : {10.0, 20.0, 30.0, 45.0}) {
      const double a = alpha * kDeg, p = 35 * kDeg, d = 20 * kDeg, b = beta * kDeg;
      const double f = dem::wedge_force(a, p, d, b);
      if (!std::isfinite(f)) continue;
      EXPECT_NEAR(f, dem::wedge_force_closed_form(a, p, d, b), 1e-12 * f) << alpha << " " << beta;
    }
}

TEST(dem_Earthmoving, TrendsAndDraftForce) {
  // Steeper blades and rougher blades draw more; the force grows with the depth squared.
  const double phi = 35 * kDeg, delta = 20 * kDeg;
  EXPECT_LT(dem::passive_wedge(30 * kDeg, phi, delta).horizontal,
            dem::passive_wedge(60 * kDeg, phi, delta).horizontal);
  EXPECT_LT(dem::passive_wedge(60 * kDeg, phi, delta).horizontal,
            dem::passive_wedge(90 * kDeg, phi, delta).horizontal);
  EXPECT_LT(dem::passive_wedge(90 * kDeg, phi, 0).n_gamma, dem::passive_wedge(90 * kDeg, phi, delta).n_gamma);
  const double f1 = dem::reece_draft(16000, 0.1, 0.5, 90 * kDeg, phi, delta);
  const double f2 = dem::reece_draft(16000, 0.2, 0.5, 90 * kDeg, phi, delta);
  EXPECT_NEAR(f2 / f1, 4.0, 1e-12);
  EXPECT_NEAR(f1, 16000 * 0.01 * 0.5 * dem::passive_wedge(90 * kDeg, phi, delta).horizontal, 1e-9);
}

TEST(dem_Earthmoving, BadAnglesAreRefusedByName) {
  auto msg = [](double a, double p, double d) {
    try {
      dem::passive_wedge(a * kDeg, p * kDeg, d * kDeg);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(msg(0, 30, 0).find("rake angle alpha"), std::string::npos);
  EXPECT_NE(msg(120, 30, 0).find("rake angle alpha"), std::string::npos);
  EXPECT_NE(msg(90, 0, 0).find("friction angle phi"), std::string::npos);
  EXPECT_NE(msg(90, NAN, 0).find("friction angle phi"), std::string::npos);
  EXPECT_NE(msg(90, 30, 35).find("delta"), std::string::npos);
  EXPECT_NE(msg(90, 30, -1).find("delta"), std::string::npos);
  EXPECT_THROW(dem::reece_draft(-1, 0.1, 1, 90 * kDeg, 30 * kDeg, 0), std::invalid_argument);
}

}  // namespace
