// Friction against closed forms: oblique impact that slides throughout, sphere on an incline
// (analytic plane and triangle mesh).
#include <gtest/gtest.h>

#include "dem/contact_law.hpp"
#include "dem_test_util.hpp"

namespace {

using namespace demtest;
using dem::State;

constexpr double kR = 0.01;

// theta is the angle between the incoming velocity and the surface NORMAL, so
// tan(theta) = v_t / v_n (35 deg is steep, 85 deg grazing). With sliding throughout the tangential impulse is mu times the
// normal impulse m v_n (1 + e), hence v_t,out / v_t,in = 1 - mu (1 + e) / tan(theta).
TEST(dem_Friction, ObliqueImpactSlidingThroughout) {
  const double mu = 0.3, speed = 1.0;
  for (double deg = 35; deg <= 85.01; deg += 10) {
    const double th = deg * M_PI / 180;
    dem::Scene scene = one_species_scene(kR, kR);
    // Clipped (the cap needs F_n >= 0 throughout); a stiff tangential spring so the contact
    // reaches the Coulomb cap within a few steps even at grazing incidence (k_T/k_N > mu tan).
    scene.particle_particle = scene.particle_wall = law_n_per_m(2e4, 0.5, true, mu, 8.0, 0.5);
    scene.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}});
    const double m = sphere_mass(kR);
    const double tc = M_PI / std::sqrt(2e4 / m);
    scene.dt = tc / 100;
    State st;
    const double vt = speed * std::sin(th), vn = speed * std::cos(th);
    add(st, {0, 0, kR + 1e-4}, {vt, 0, -vn}, kR);
    dem::Engine engine(scene);
    for (int k = 0; k < 2000 && !(st.x[0].z > kR + 1e-4 && st.v[0].z > 0); ++k) engine.step(st);
    for (int k = 0; k < 5; ++k) engine.step(st);
    const double e = st.v[0].z / vn;  // actual (clipped) restitution of this impact
    const double ratio = st.v[0].x / vt;
    const double want = 1 - mu * (1 + e) / std::tan(th);
    std::printf("theta %4.1f deg: v_t ratio %.5f, 1 - mu(1+e)/tan = %.5f (e = %.4f)\n", deg, ratio,
                want, e);
    EXPECT_NEAR(ratio, want, 0.01) << "theta " << deg;
  }
}

struct InclineResult {
  double accel, travel_late;
};

// Sphere resting (at its static overlap) on an incline of angle theta under gravity. Returns
// the acceleration along the slope measured between 0.1 s and 0.3 s, and the distance moved
// between 0.2 s and 0.3 s.
InclineResult incline(double theta, double mu, bool mesh) {
  dem::Scene scene = one_species_scene(kR, kR);
  scene.gravity = {0, 0, -9.81};
  scene.particle_particle = scene.particle_wall = law_n_per_m(2e4, 0.3, true, mu, 1.0, 0.5);
  const Vec3 n{std::sin(theta), 0, std::cos(theta)};
  const Vec3 down{std::cos(theta), 0, -std::sin(theta)};  // along the slope, downhill
  const Vec3 across{0, 1, 0};
  if (mesh) {
    // A long rectangle in the incline plane split along its diagonal: the sphere crosses the
    // shared edge while it slides.
    const double L = 2.0, W = 0.05;
    std::vector<Vec3> c;
    const Vec3 o = (-0.2) * down + (-W / 2) * across;
    const Vec3 a = o, b = o + L * down, cc = o + L * down + W * across, d = o + W * across;
    c.insert(c.end(), {a, b, cc, a, cc, d});
    scene.tools.push_back(static_tool("incline", c));
  } else {
    scene.walls.push_back({"incline", {0, 0, 0}, n});
  }
  const double m = sphere_mass(kR);
  scene.dt = M_PI / std::sqrt(2e4 / m) / 50;
  State st;
  const double overlap = m * 9.81 * std::cos(theta) / 2e4;
  add(st, (kR - overlap) * n, {}, kR);
  st.tool_pose.resize(scene.tools.size());
  dem::Engine engine(scene);
  auto run_to = [&](double t) {
    while (st.step * scene.dt < t) engine.step(st);
  };
  run_to(0.1);
  const double v1 = dot(st.v[0], down), t1 = st.step * scene.dt;
  run_to(0.2);
  const double s2 = dot(st.x[0], down);
  run_to(0.3);
  const double v3 = dot(st.v[0], down), t3 = st.step * scene.dt;
  return {(v3 - v1) / (t3 - t1), dot(st.x[0], down) - s2};
}

TEST(dem_Friction, InclineRestsWhileTanBelowMuElseSlides) {
  const double mu = 0.4, g = 9.81;
  for (bool mesh : {false, true}) {
    for (double tan_ratio : {0.5, 0.95, 1.2, 2.0}) {
      const double th = std::atan(tan_ratio * mu);
      const InclineResult r = incline(th, mu, mesh);
      const char* what = mesh ? "mesh" : "plane";
      if (tan_ratio <= 1) {
        std::printf("%s tan/mu %.2f: travel in 0.1 s %.3e m\n", what, tan_ratio, r.travel_late);
        EXPECT_LT(std::abs(r.travel_late), 1e-9) << what << " creeps at tan/mu " << tan_ratio;
        EXPECT_LT(std::abs(r.accel), 1e-6) << what;
      } else {
        const double want = g * (std::sin(th) - mu * std::cos(th));
        std::printf("%s tan/mu %.2f: a = %.6f, g(sin - mu cos) = %.6f (%+.4f %%)\n", what,
                    tan_ratio, r.accel, want, 100 * (r.accel / want - 1));
        EXPECT_NEAR(r.accel, want, 0.005 * want) << what << " tan/mu " << tan_ratio;
      }
    }
  }
}

}  // namespace
