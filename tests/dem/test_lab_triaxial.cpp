// The virtual triaxial test (dem/lab/triaxial.hpp, docs/soil_lab.md) on small samples: the
// servo holds the confining stress, the friction angle grows with the contact friction beyond
// the scatter between samples, a frictionless preparation reaches random close packing, and the
// Mohr-Coulomb fit returns the angle and cohesion of circles made from them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "cosim/yaml_config.hpp"
#include "dem/lab/triaxial.hpp"

namespace {

namespace lab = dem::lab;

// The main job's particle law (configs/soil/pile.yaml), 300 grains, one confining pressure.
lab::TriaxialOptions small(long count = 300, const std::string& extra = "") {
  const std::string text = R"(
grains:
  density: 2600
  radius: {min: 0.06, max: 0.075}
  contact: {normal_stiffness: 4.0e7, restitution: 0.3, tangential_stiffness_ratio: 0.5,
            tangential_damping_ratio: 0.5, friction: 0.5}
sample: {count: )" + std::to_string(count) + R"(, seed: 1}
triaxial:
  confining_pressures: [10.0e3]
  inertial_number: 2.0e-3
  max_axial_strain: 0.04
  record_every: 0.002
)" + extra;
  return lab::parse_triaxial(cosim::config::load_string(text, "test"));
}

double sin_deg(double a) { return std::sin(a * M_PI / 180); }

TEST(dem_LabTriaxial, ServoHoldsTheConfiningStressWithinTwoPercent) {
  const lab::TriaxialOptions o = small();
  const lab::Sample sample = lab::prepare_sample(o, 10e3);
  const lab::TriaxialTest t = lab::run_triaxial(o, sample, 10e3);
  ASSERT_GE(t.curve.size(), 15u);
  // It sheared: the axial stress rose well above the confining one and the sample dilated.
  EXPECT_GT(t.curve.back().sigma1, 3 * 10e3);
  EXPECT_LT(t.curve.back().volumetric_strain, t.curve[5].volumetric_strain);
  // Every lateral wall, averaged over each record (0.2 % strain), within 2 % of 10 kPa.
  std::printf("worst lateral wall off by %.2f %%\n", 100 * t.servo_worst);
  EXPECT_LT(t.servo_worst, 0.02);
  for (std::size_t i = 3; i < t.curve.size(); ++i)
    EXPECT_NEAR(t.curve[i].sigma3, 10e3, 0.02 * 10e3) << "record " << i;
  // The strain is the walls': the axial strain steps by record_every.
  EXPECT_NEAR(t.curve.back().axial_strain, 0.04, 1e-3);
  // The rate the inertial number asked for.
  EXPECT_NEAR(t.inertial_number, 2e-3, 1e-9);
}

TEST(dem_LabTriaxial, FrictionAngleGrowsWithMuBeyondTheSampleScatter) {
  // Two samples (seeds), three friction coefficients, the same preparation for each seed.
  const double mus[3] = {0.1, 0.3, 0.6};
  double lo[3], hi[3];
  for (int k = 0; k < 3; ++k) lo[k] = 90, hi[k] = 0;
  for (int seed = 1; seed <= 2; ++seed) {
    lab::TriaxialOptions o = small(300, "");
    o.seed = static_cast<std::uint64_t>(seed);
    o.max_axial_strain = 0.05;
    const lab::Sample sample = lab::prepare_sample(o, 10e3);
    for (int k = 0; k < 3; ++k) {
      o.grains.law.friction = mus[k];
      const lab::TriaxialTest t = lab::run_triaxial(o, sample, 10e3);
      // the peak angle is the largest mobilised one and equals sin(phi) = q / (s1 + s3) there
      const auto& pk = t.curve[t.peak];
      EXPECT_NEAR(sin_deg(t.phi_peak), (pk.sigma1 - pk.sigma3) / (pk.sigma1 + pk.sigma3), 1e-9);
      lo[k] = std::min(lo[k], t.phi_peak);
      hi[k] = std::max(hi[k], t.phi_peak);
      std::printf("mu %.1f seed %d: peak phi %.2f deg\n", mus[k], seed, t.phi_peak);
    }
  }
  double scatter = 0;
  for (int k = 0; k < 3; ++k) scatter = std::max(scatter, hi[k] - lo[k]);
  for (int k = 0; k < 2; ++k) {
    // The weakest sample of the higher mu beats the strongest of the lower mu by more than
    // three times the largest spread between two samples of one mu, and by 5 degrees.
    const double gap = lo[k + 1] - hi[k];
    EXPECT_GT(gap, 3 * scatter) << "mu " << mus[k] << " -> " << mus[k + 1];
    EXPECT_GT(gap, 5.0) << "mu " << mus[k] << " -> " << mus[k + 1];
  }
}

TEST(dem_LabTriaxial, FrictionlessPreparationReachesRandomClosePacking) {
  // Agnolin & Roux (2007): frictionless spheres compressed isotropically assemble at random
  // close packing, 0.639; measured away from the walls (they order the first layers).
  lab::TriaxialOptions o = small(800);
  o.grains.law.friction = 0;
  const lab::Sample sample = lab::prepare_sample(o, 10e3);
  const double m = 2 * o.grains.radius_max;
  const double inner = lab::packing_fraction(sample.state, sample.lo + dem::Vec3{m, m, m},
                                             sample.hi - dem::Vec3{m, m, m});
  EXPECT_NEAR(inner, 0.64, 0.02);
  // The whole box holds less: the walls leave gaps beside them.
  EXPECT_LT(lab::packing_fraction(sample.state, sample.lo, sample.hi), inner);
}

TEST(dem_LabTriaxial, PackingFractionCountsCutGrainsByTheirCaps) {
  dem::State s;
  dem::add_particle(s, {0, 0, 0}, {}, 1.0, 1.0, 0, 0);
  // A box holding the whole sphere: 4/3 pi; half of it: 2/3 pi; a cap of height 0.5.
  EXPECT_NEAR(lab::packing_fraction(s, {-2, -2, -2}, {2, 2, 2}) * 64, 4.0 / 3.0 * M_PI, 1e-12);
  EXPECT_NEAR(lab::packing_fraction(s, {0, -2, -2}, {4, 2, 2}) * 64, 2.0 / 3.0 * M_PI, 1e-12);
  EXPECT_NEAR(lab::packing_fraction(s, {0.5, -2, -2}, {4.5, 2, 2}) * 64,
              M_PI * 0.25 * (3 - 0.5) / 3, 1e-12);
  EXPECT_NEAR(lab::packing_fraction(s, {-4.5, -2, -2}, {-0.5, 2, 2}) * 64,
              M_PI * 0.25 * (3 - 0.5) / 3, 1e-12);
}

TEST(dem_LabTriaxial, MohrCoulombFitReturnsTheEnvelopeOfItsCircles) {
  // Circles touching t = c cos(phi) + s sin(phi): sigma1 from sigma3 by the Mohr-Coulomb
  // relation sigma1 = sigma3 tan^2(45 + phi/2) + 2 c tan(45 + phi/2).
  const double phi = 38 * M_PI / 180, c = 2e3;
  const double N = std::tan(M_PI / 4 + phi / 2);
  std::vector<double> s1, s3;
  for (double p : {10e3, 20e3, 40e3}) {
    s3.push_back(p);
    s1.push_back(p * N * N + 2 * c * N);
  }
  const lab::MohrCoulombFit f = lab::fit_mohr_coulomb(s1, s3);
  EXPECT_NEAR(f.phi, 38.0, 1e-9);
  EXPECT_NEAR(f.cohesion, c, 1e-6);
  EXPECT_NEAR(f.phi_stderr, 0.0, 1e-6);
  // Without cohesion, the fit through the origin gives the angle of every circle.
  for (double& v : s1) v = 0;
  for (std::size_t i = 0; i < s3.size(); ++i) s1[i] = s3[i] * N * N;
  const lab::MohrCoulombFit g = lab::fit_mohr_coulomb(s1, s3);
  EXPECT_NEAR(g.phi_origin, 38.0, 1e-9);
  EXPECT_NEAR(g.cohesion, 0.0, 1e-6);
  // sin(phi) = (s1 - s3) / (s1 + s3) for one circle
  EXPECT_NEAR((s1[0] - s3[0]) / (s1[0] + s3[0]), std::sin(phi), 1e-12);
}

}  // namespace
