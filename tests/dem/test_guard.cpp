// The guard that rebuilds the lists "when needed" uses the two largest displacements (of two
// different particles) instead of twice the largest: one fast particle alone moves a whole skin
// before the bound fires; with guard: rebuild its far-mover check then lets a lone particle fly
// on without a broad phase; two fast particles flying at each other are caught, and no contact
// is missed on the way (dem_broad_phase_test checks the lists against a brute-force search).
#include <gtest/gtest.h>

#include <algorithm>

#include "dem_test_util.hpp"

namespace {

using namespace demtest;
using dem::State;


// Particles at rest on a lattice (no gravity, no walls) and one fast particle flying along a
// free lane between them. The guard's bound fires when that particle alone has moved the skin
// (the others did not move), not half of it as a bound of twice the largest displacement would:
// in strict mode that is the step it throws. With guard: rebuild the far-mover check then sees
// that the lone particle comes near nothing it is not listed with: no broad phase at all.
dem::Scene lane_scene() {
  const double r = 1e-3;
  dem::Scene scene = one_species_scene(r, r);
  scene.particle_particle = scene.particle_wall = law_n_per_m(100, 0.5, true, 0.5);
  scene.broad_phase_interval = 1 << 30;
  scene.skin = 0.5;  // 0.5 mm
  scene.dt = 1e-5;
  return scene;
}

State lane_state(double speed) {
  const double r = 1e-3;
  State st;
  const double pitch = 2.6 * r;
  for (int ix = 0; ix < 12; ++ix)
    for (int iy = 0; iy < 3; ++iy)
      if (iy != 1) add(st, {ix * pitch, iy * pitch, 0}, {}, r);
  add(st, {0, pitch, 0}, {speed, 0, 0}, r);
  return st;
}

TEST(dem_Guard, GuardWaitsForTheTwoLargestDisplacements) {
  dem::Scene scene = lane_scene();
  scene.guard = dem::GuardMode::strict;
  const double speed = 1.0;  // 1e-5 m a step: the skin in 50 steps
  State st = lane_state(speed);
  dem::Engine engine(scene);
  engine.step(st);  // the first broad phase
  int first = -1;
  for (int k = 1; k < 200 && first < 0; ++k) {
    try {
      engine.step(st);
    } catch (const dem::SimulationError&) {
      first = k;
    }
  }
  ASSERT_GT(first, 0) << "the guard never fired";
  // Fired after the fast particle moved the skin (within a step), not half of it.
  const double per_step = speed * scene.dt, skin = scene.skin_distance();
  EXPECT_GT(first * per_step, skin - 2 * per_step) << first;
  EXPECT_LT(first * per_step, skin + 2 * per_step) << first;
}

TEST(dem_Guard, LoneFastParticleInAFreeLaneNeedsNoBroadPhase) {
  const dem::Scene scene = lane_scene();  // guard: rebuild
  State st = lane_state(1.0);
  dem::Engine engine(scene);
  for (int k = 0; k < 150; ++k) engine.step(st);  // three skins
  EXPECT_EQ(st.rebuilds, 1);  // the first
  EXPECT_EQ(st.early_rebuilds, 0);
  EXPECT_GT(engine.guard_cleared(), 90);  // every step after the first skin
  EXPECT_GT(st.max_displacement, 2.5 * scene.skin_distance());
}

// Two fast particles flying at each other, starting just beyond the skin, in a bed at rest:
// the guard sees both displacements and the lists hold their contact when it comes.
TEST(dem_Guard, GuardCatchesTwoFastParticlesMeetingHeadOn) {
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

// The contact law acts from a gap below dt/2 |v_n| on (the step's window), so a pair must be in
// the lists before its gap closes to zero. Two particles close at 9.95e-6 m a step from 1e-6 m
// beyond the skin: at step 50 their gap is 3.5e-6 m, inside the window (4.975e-6 m), while the
// two displacements add up to 4.975e-4 m, less than the skin (5e-4 m). A bound without the
// window would not fire there and the step's partial force would be lost.
TEST(dem_Guard, BoundCountsTheContactWindow) {
  const double r = 1e-3;
  dem::Scene scene = one_species_scene(r, r);
  scene.particle_particle = scene.particle_wall = law_n_per_m(100, 0.5, true, 0.5);
  scene.broad_phase_interval = 1 << 30;
  scene.skin = 0.5;  // 5e-4 m
  scene.dt = 1e-5;
  const double speed = 0.4975, skin = scene.skin_distance(), dt = scene.dt;
  State st;
  add(st, {0, 0, 0}, {speed, 0, 0}, r);
  add(st, {2 * r + skin + 1e-6, 0, 0}, {-speed, 0, 0}, r);
  dem::Engine engine(scene);
  int in_window = 0;
  for (int k = 0; k < 60; ++k) {
    engine.prepare(st);
    const std::size_t a = index_of(st, 0), b = index_of(st, 1);
    const double gap = dem::norm(st.x[a] - st.x[b]) - 2 * r;
    const double window = 0.5 * dt * std::abs(st.u[a].x - st.u[b].x);
    if (gap < window) {
      const std::size_t i = std::min(a, b), j = std::max(a, b);
      bool listed = false;
      for (std::int32_t q = st.pair_offset[i]; q < st.pair_offset[i + 1]; ++q)
        listed |= static_cast<std::size_t>(st.pair_j[q]) == j;
      ASSERT_TRUE(listed) << "step " << k << ": gap " << gap << " m inside the window "
                          << window << " m, the pair not in the lists";
      if (gap > 0) ++in_window;
    }
    engine.step(st);
  }
  EXPECT_GE(in_window, 1);  // the case the test is about happened
  EXPECT_LT(std::abs(st.v[index_of(st, 0)].x), 0.99 * speed);  // and the contact acted
}

}  // namespace
