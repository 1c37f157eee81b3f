// The step's one parallel region (docs/performance.md, "One pass per step"): with
// scene.fused_step a particle's wall and mesh contacts and its integration follow its row of
// pair forces; the particle states must be bit-identical to the three separate passes, for 1, 2
// and 3 threads, with and without sleeping, through walls and a moving mesh tool. And the guard
// that rebuilds the lists "when needed" uses the two largest displacements: one fast particle
// alone moves a whole skin before it fires, and no contact is missed on the way.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>

#include "dem_test_util.hpp"

namespace {

using namespace demtest;
using dem::State;

constexpr double kRmin = 0.9e-3, kRmax = 1.1e-3;

// A polydisperse bed poured into a box (five walls) under gravity, with friction, and a folded
// plate moving down into it: pair, wall and mesh contacts, history everywhere.
std::pair<dem::Scene, State> poured_bed(int threads, bool sleep, bool fused) {
  dem::Scene scene = one_species_scene(kRmin, kRmax);
  scene.gravity = {0, 0, -9.81};
  scene.threads = threads;
  scene.min_particles_per_thread = 1;
  scene.broad_phase_interval = 10;
  scene.fused_step = fused;
  scene.particle_particle = scene.particle_wall = law_n_per_m(200, 0.4, true, 0.5);
  const double L = 0.024;
  scene.walls = {{"x0", {0, 0, 0}, {1, 0, 0}},  {"x1", {L, 0, 0}, {-1, 0, 0}},
                 {"y0", {0, 0, 0}, {0, 1, 0}},  {"y1", {0, L, 0}, {0, -1, 0}},
                 {"z0", {0, 0, 0}, {0, 0, 1}}};
  std::vector<Vec3> c;
  const double w = 0.006;
  quad(c, {-w, -w, 0}, {0, -w, 0.3 * w}, {0, w, 0.3 * w}, {-w, w, 0});
  quad(c, {0, -w, 0.3 * w}, {w, -w, 0}, {w, w, 0}, {0, w, 0.3 * w});
  dem::Tool tool = static_tool("plate", c);
  tool.motion.keyframes = {{0, {0.012, 0.012, 0.03}, {1, 0, 0, 0}},
                           {0.06, {0.012, 0.012, 0.004}, {0.9238795, 0.3826834, 0, 0}}};
  scene.tools.push_back(tool);
  if (sleep) {
    scene.sleep.enabled = true;
    scene.sleep.speed = 0.02;
    scene.sleep.steps = 50;
    scene.sleep.tool_distance = 0.001;
    scene.sleep.neighbourhood = dem::SleepNeighbourhood::box;
  }
  State st;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(0, 1);
  const double h = 2 * kRmax * 1.02;
  for (int iz = 0; iz < 9; ++iz)
    for (int iy = 0; iy < 10; ++iy)
      for (int ix = 0; ix < 10; ++ix) {
        const double r = kRmin + (kRmax - kRmin) * U(rng);
        add(st, {kRmax + ix * h + 0.1e-3 * U(rng), kRmax + iy * h + 0.1e-3 * U(rng),
                 kRmax + iz * h},
            {0.05 * (2 * U(rng) - 1), 0.05 * (2 * U(rng) - 1), 0}, r);
      }
  scene.dt = 2e-5;
  st.tool_pose = {tool.motion.evaluate(0)};
  return {scene, st};
}

template <class T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

TEST(dem_Step, FusedStepGivesTheParticleStatesOfThreePasses) {
  for (const bool sleep : {false, true})
    for (const int threads : {1, 2, 3}) {
      auto [scene_a, a] = poured_bed(threads, sleep, true);
      auto [scene_b, b] = poured_bed(threads, sleep, false);
      dem::Engine ea(scene_a), eb(scene_b);
      std::int64_t mesh_contacts = 0, wall_steps = 0, max_asleep = 0;
      for (int k = 0; k < 3000; ++k) {
        for (State* s : {&a, &b}) s->tool_pose[0] = scene_a.tools[0].motion.evaluate(s->step * scene_a.dt);
        ea.step(a);
        eb.step(b);
        mesh_contacts += norm2(ea.tool_wrenches()[0].force) > 0;
        wall_steps += norm2(ea.wall_forces()[4]) > 0;
        max_asleep = std::max(max_asleep, ea.sleeping());
        // The wrenches are the same contacts summed in another grouping.
        const Vec3 fa = ea.tool_wrenches()[0].force, fb = eb.tool_wrenches()[0].force;
        ASSERT_TRUE(same_bytes(a.x, b.x)) << "step " << k;
        ASSERT_LE(norm(fa - fb), 1e-12 * (1 + norm(fb))) << "step " << k;
      }
      const std::string what = std::to_string(threads) + " threads, sleep " + (sleep ? "on" : "off");
      EXPECT_EQ(ea.threads(), threads) << what;
      EXPECT_TRUE(same_bytes(a.x, b.x)) << what;
      EXPECT_TRUE(same_bytes(a.v, b.v)) << what;
      EXPECT_TRUE(same_bytes(a.u, b.u)) << what;
      EXPECT_TRUE(same_bytes(a.pair_spring, b.pair_spring)) << what;
      EXPECT_TRUE(same_bytes(a.slot_spring, b.slot_spring)) << what;
      EXPECT_TRUE(same_bytes(a.slot_key, b.slot_key)) << what;
      EXPECT_EQ(a.rest_steps, b.rest_steps) << what;
      EXPECT_EQ(a.rebuilds, b.rebuilds) << what;
      // Not vacuous: the bed touched the floor and the plate, and sleepers came and went.
      EXPECT_GT(wall_steps, 2500) << what;
      EXPECT_GT(mesh_contacts, 200) << what;
      if (sleep) {
        EXPECT_GT(max_asleep, 50) << what;
      }
      EXPECT_GT(a.early_rebuilds + a.rebuilds, 100) << what;
    }
}

// Particles at rest on a lattice (no gravity, no walls) and one fast particle flying along a
// free lane between them: the guard fires when that particle alone has moved the skin (the
// others did not move), not half of it as a bound of twice the largest displacement would.
TEST(dem_Step, GuardWaitsForTheTwoLargestDisplacements) {
  const double r = 1e-3;
  dem::Scene scene = one_species_scene(r, r);
  scene.particle_particle = scene.particle_wall = law_n_per_m(100, 0.5, true, 0.5);
  scene.broad_phase_interval = 1 << 30;
  scene.skin = 0.5;  // 0.5 mm
  scene.dt = 1e-5;
  State st;
  const double pitch = 2.6 * r;
  for (int ix = 0; ix < 12; ++ix)
    for (int iy = 0; iy < 3; ++iy)
      if (iy != 1) add(st, {ix * pitch, iy * pitch, 0}, {}, r);
  const double speed = 1.0;  // 1e-5 m a step: the skin in 50 steps
  add(st, {0, pitch, 0}, {speed, 0, 0}, r);
  dem::Engine engine(scene);
  engine.step(st);  // the first broad phase
  ASSERT_EQ(st.early_rebuilds, 0);
  const double per_step = speed * scene.dt, skin = scene.skin_distance();
  int first = -1;
  for (int k = 1; k < 200 && first < 0; ++k) {
    engine.step(st);
    if (st.early_rebuilds > 0) first = k;
  }
  ASSERT_GT(first, 0) << "the guard never fired";
  // Fired after the fast particle moved the skin (within a step), not half of it.
  EXPECT_GT(first * per_step, skin - 2 * per_step) << first;
  EXPECT_LT(first * per_step, skin + 2 * per_step) << first;
}

// Two fast particles flying at each other, starting just beyond the skin, in a bed at rest:
// the guard sees both displacements and the lists hold their contact when it comes.
TEST(dem_Step, GuardCatchesTwoFastParticlesMeetingHeadOn) {
  const double r = 1e-3;
  dem::Scene scene = one_species_scene(r, r);
  scene.particle_particle = scene.particle_wall = law_n_per_m(100, 0.5, true, 0.5);
  scene.broad_phase_interval = 1 << 30;
  scene.skin = 0.5;
  scene.dt = 1e-5;
  State st;
  for (int ix = 0; ix < 6; ++ix) add(st, {ix * 2.6 * r, 0, 0}, {}, r);
  const double gap = scene.skin_distance() * 1.01;
  add(st, {0, 4 * r, 0}, {0.5, 0, 0}, r);
  add(st, {2 * r + gap, 4 * r, 0}, {-0.5, 0, 0}, r);
  dem::Engine engine(scene);
  bool touched = false;
  for (int k = 0; k < 400; ++k) {
    engine.prepare(st);
    const auto c = engine.particle_contacts(st);
    const std::size_t a = index_of(st, 6), b = index_of(st, 7);
    const bool overlap = norm2(st.x[a] - st.x[b]) < 4 * r * r;
    const bool listed = std::find(c.begin(), c.end(), std::make_pair<std::int64_t, std::int64_t>(6, 7)) != c.end();
    ASSERT_EQ(overlap, listed) << "step " << k;
    touched |= overlap;
    engine.step(st);
  }
  EXPECT_TRUE(touched);
  EXPECT_GT(st.early_rebuilds, 0);
}

}  // namespace
