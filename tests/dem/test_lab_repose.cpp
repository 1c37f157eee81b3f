// The virtual angle-of-repose test (dem/lab/repose.hpp, docs/soil_lab.md): the surface fit
// returns the angle of a cone made of grains, and the heap of a lifted cylinder stands steeper
// with more contact friction (the grains cannot rotate, so friction alone holds the slope).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

#include "cosim/yaml_config.hpp"
#include "dem/lab/repose.hpp"

namespace {

namespace lab = dem::lab;

TEST(dem_LabRepose, SurfaceFitReturnsTheAngleOfACone) {
  // A cone of slope angle a: grains (r = 0.05) filling it on a square grid with jitter; the
  // highest grain top in each ring lies on the cone within about a grain.
  for (double a : {25.0, 40.0, 55.0}) {
    const double r = 0.05, H = 1.0, t = std::tan(a * M_PI / 180), R = H / t;
    std::vector<dem::Vec3> x;
    std::vector<double> rad;
    std::uint64_t k = 1;
    auto jitter = [&]() {
      k = k * 6364136223846793005ull + 1442695040888963407ull;
      return (static_cast<double>(k >> 11) * 0x1.0p-53 - 0.5) * 0.02;
    };
    for (double px = -R; px <= R; px += 2 * r)
      for (double py = -R; py <= R; py += 2 * r) {
        const double rr = std::hypot(px, py);
        const double top = H - rr * t;  // cone surface height here
        for (double pz = r; pz + r <= top; pz += 2 * r) {
          x.push_back({px + jitter(), py + jitter(), pz});
          rad.push_back(r);
        }
      }
    const lab::ReposeResult f = lab::fit_heap(x, rad, 0.0, 2 * r, 8);
    EXPECT_NEAR(f.angle, a, 2.0) << "cone of " << a << " deg";
    EXPECT_EQ(f.sectors, 8);
    EXPECT_NEAR(f.pile_radius, R, 0.1 * R);
  }
}

lab::ReposeOptions heap(double mu) {
  const std::string text = R"(
grains:
  density: 2600
  radius: {min: 0.06, max: 0.075}
  contact: {normal_stiffness: 4.0e7, restitution: 0.3, tangential_stiffness_ratio: 0.5,
            tangential_damping_ratio: 0.5, friction: )" + std::to_string(mu) + R"(}
repose: {count: 300, seed: 1}
)";
  return lab::parse_repose(cosim::config::load_string(text, "test"));
}

TEST(dem_LabRepose, HeapStandsSteeperWithMoreFriction) {
  const lab::ReposeResult low = lab::run_repose(heap(0.1));
  const lab::ReposeResult high = lab::run_repose(heap(0.6));
  std::printf("angle of repose: mu 0.1 %.1f deg (+- %.1f), mu 0.6 %.1f deg (+- %.1f)\n",
              low.angle, low.angle_sd, high.angle, high.angle_sd);
  // Every grain stays on the base, the heaps are heaps (an angle between 5 and 80 degrees).
  EXPECT_EQ(low.count + low.lost, 300);
  EXPECT_GT(low.angle, 5.0);
  EXPECT_LT(high.angle, 80.0);
  // Measured 14.6 and 57.1 deg (docs/soil_lab.md); a second seed gives 15.3 and 64.3: the
  // difference is 6 times the seed-to-seed change.
  EXPECT_GT(high.angle - low.angle, 20.0);
  EXPECT_GT(high.height, low.height);
}

}  // namespace
