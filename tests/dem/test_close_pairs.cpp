// Close pairs (performance.close_margin): the pair forces read only the candidates within a margin
// of contact (and every candidate of a fast particle), re-listed when the slow particles may
// have closed the margin. They change no result: every array of State after a run is the same,
// bit for bit, as with every candidate read, on either kernel, 1 or 2 threads, with margins
// small enough to re-list often, and when a state is put back to an earlier step (the DEM
// service's repeated macro steps).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "dem_test_util.hpp"

namespace {

using demtest::Vec3;

// A polydisperse lattice with gaps inside the skin, creeping at up to 4 mm/s (some below the
// fast speed of the margin, some above), and 60 grains thrown through it at 0.5 m/s: collisions
// spread from them, friction holds springs, contacts end and new ones begin.
dem::Scene lattice_scene(int threads) {
  dem::Scene scene = demtest::one_species_scene(0.8e-3, 1.2e-3);
  scene.threads = threads;
  scene.broad_phase_interval = 1 << 30;  // when needed
  scene.particle_particle = scene.particle_wall = demtest::law_n_per_m(500, 0.3, true, 0.5);
  scene.dt = 2e-5;
  return scene;
}

// Its engine: close pairs within `margin` (fast above margin * 1.2e-3 / (800 dt): 3.75 mm/s
// at 0.05), every thread asked for used (100 particles per thread are enough).
dem::EngineOptions lattice_options(double margin,
                                   dem::EngineOptions::PairKernel kernel =
                                       dem::EngineOptions::PairKernel::vector) {
  dem::EngineOptions o;
  o.pair_kernel = kernel;
  o.min_particles_per_thread = 100;
  o.close_margin = margin;
  return o;
}

dem::State lattice_state() {
  dem::State st;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U01(0, 1);
  const double pitch = 2.5e-3;
  for (int k = 0; k < 1500; ++k) {
    const double r = 0.8e-3 + 0.4e-3 * U01(rng);
    Vec3 v{U01(rng) - 0.5, U01(rng) - 0.5, U01(rng) - 0.5};
    v = (4e-3 * U01(rng) / std::max(1e-9, dem::norm(v))) * v;
    if (k % 25 == 0) v = {0.5, 0.1 * (U01(rng) - 0.5), 0.1 * (U01(rng) - 0.5)};
    demtest::add(st, {pitch * (k % 12), pitch * ((k / 12) % 12), pitch * (k / 144)}, v, r);
  }
  return st;
}

// The comparison the tests below rest on names what differs, and only that.
TEST(dem_ClosePairs, DifferingArraysNamesTheArrays) {
  const dem::Scene scene = lattice_scene(1);
  dem::State a = lattice_state();
  dem::Engine engine(scene, lattice_options(0.0));
  for (int k = 0; k < 50; ++k) engine.step(a);
  dem::State b = a;
  EXPECT_EQ(dem::differing_arrays(a, b), "");
  ASSERT_FALSE(b.pair_spring.empty());
  b.pair_spring.back().x = std::nextafter(b.pair_spring.back().x, 1.0);
  b.u[7].z = -b.u[7].z;  // the sign bit flips, even of a zero
  EXPECT_EQ(dem::differing_arrays(a, b), " u pair_spring");
  b.rest_steps.push_back(0);
  EXPECT_EQ(dem::differing_arrays(a, b), " u pair_spring rest_steps");
}

TEST(dem_ClosePairs, SameBitsAsEveryCandidate) {
  for (const dem::EngineOptions::PairKernel kernel : demtest::pair_kernels()) {
    for (const int threads : {1, 2}) {
      dem::State reference = lattice_state();
      {
        const dem::Scene scene = lattice_scene(threads);
        dem::Engine engine(scene, lattice_options(0.0, kernel));
        std::int64_t contact_steps = 0;  // touching pairs, summed over the steps
        for (int k = 0; k < 1200; ++k) {
          engine.step(reference);
          contact_steps += engine.contact_stats().particle_contacts;
        }
        EXPECT_GT(contact_steps, 10000);
        EXPECT_EQ(engine.close_builds(), 0);
      }
      for (const double margin : {0.05, 0.2}) {
        const dem::Scene scene = lattice_scene(threads);
        dem::State st = lattice_state();
        dem::Engine engine(scene, lattice_options(margin, kernel));
        std::int64_t used_steps = 0;
        for (int k = 0; k < 1200; ++k) {
          engine.step(st);
          used_steps += engine.close_share() > 0 && engine.close_share() <= 0.9;
        }
        // The close pairs were listed more often than the broad phase ran, and read.
        EXPECT_GT(engine.close_builds(), st.rebuilds) << margin;
        EXPECT_GT(used_steps, 600) << margin;
        EXPECT_LT(engine.close_share(), 0.9) << margin;
        EXPECT_EQ(dem::differing_arrays(reference, st), "")
            << "margin " << margin << ", " << threads << " thread(s), "
            << demtest::kernel_name(kernel) << " kernel";
      }
    }
  }
}

// With sleepers (scene.sleep) the close pairs change no result either: the creeping grains fall
// asleep, the thrown ones wake them, and every array of State is the same as with every
// candidate read, on either kernel and 1 or 2 threads. Fails if a sleeper pair's spring is
// dropped at listing, if the sleeping integration stops tracking the displacements since the
// listing, or if the vector kernel's row loop writes a copy without its home.
TEST(dem_ClosePairs, SameBitsAsEveryCandidateWithSleepers) {
  for (const dem::EngineOptions::PairKernel kernel : demtest::pair_kernels()) {
    for (const int threads : {1, 2}) {
      dem::State result[2];
      std::int64_t sleeper_steps[2] = {0, 0};
      for (const double margin : {0.0, 0.05}) {
        dem::Scene scene = lattice_scene(threads);
        scene.sleep.enabled = true;
        scene.sleep.speed = 3e-3;  // most creeping grains fall asleep; hits wake them
        scene.sleep.steps = 20;
        scene.sleep.tool_distance = 0;
        scene.sleep.close_pairs = true;  // off by default with sleeping
        dem::State st = lattice_state();
        dem::Engine engine(scene, lattice_options(margin, kernel));
        for (int k = 0; k < 1200; ++k) {
          engine.step(st);
          sleeper_steps[margin > 0] += engine.sleeping();
        }
        if (margin > 0) {
          EXPECT_GT(engine.close_builds(), st.rebuilds);
          EXPECT_LT(engine.close_share(), 0.9);
        } else {
          EXPECT_EQ(engine.close_builds(), 0);
        }
        result[margin > 0] = st;
      }
      EXPECT_GT(sleeper_steps[0], 200000);  // of 1,800,000 particle-steps
      EXPECT_EQ(sleeper_steps[0], sleeper_steps[1]);
      EXPECT_EQ(dem::differing_arrays(result[0], result[1]), "")
          << threads << " thread(s), " << demtest::kernel_name(kernel) << " kernel";
    }
  }
}

// With sleeping on, close pairs are listed only when scene.sleep.close_pairs asks for them.
TEST(dem_ClosePairs, OffWithSleepingUnlessAsked) {
  for (const bool asked : {false, true}) {
    dem::Scene scene = lattice_scene(1);
    scene.sleep.enabled = true;
    scene.sleep.speed = 3e-3;
    scene.sleep.steps = 20;
    scene.sleep.tool_distance = 0;
    scene.sleep.close_pairs = asked;
    EXPECT_EQ(dem::close_pairs_on(scene, lattice_options(0.05)), asked);
    dem::State st = lattice_state();
    dem::Engine engine(scene, lattice_options(0.05));
    for (int k = 0; k < 50; ++k) engine.step(st);
    if (asked)
      EXPECT_GT(engine.close_builds(), 0);
    else
      EXPECT_EQ(engine.close_builds(), 0);
  }
}

// A repeated macro step puts the state back (copy assignment into the same object): the close
// pairs listed for the abandoned steps must not be used for it.
TEST(dem_ClosePairs, StatePutBackIsListedAgain) {
  dem::State result[2];
  for (const double margin : {0.0, 0.05}) {
    const dem::Scene scene = lattice_scene(1);
    dem::State st = lattice_state();
    dem::Engine engine(scene, lattice_options(margin));
    for (int k = 0; k < 600; ++k) engine.step(st);
    const dem::State snapshot = st;
    for (int k = 0; k < 40; ++k) engine.step(st);
    st = snapshot;  // the repeat
    for (int k = 0; k < 40; ++k) engine.step(st);
    result[margin > 0] = st;
  }
  EXPECT_EQ(dem::differing_arrays(result[0], result[1]), "");
}

// Two slow particles closing on each other from beyond the margin, in a lattice at rest: the
// listing must let them meet at the step they meet with every candidate read.
TEST(dem_ClosePairs, SlowApproachFromBeyondTheMarginIsCaught) {
  const double r = 1e-3;
  dem::Scene scene = demtest::one_species_scene(r, r);
  scene.particle_particle = scene.particle_wall = demtest::law_n_per_m(100, 0.5, true, 0.5);
  scene.broad_phase_interval = 1 << 30;
  scene.skin = 0.5;           // 0.5 mm
  // Close pairs within 0.05 r = 50 um: fast above 50e-6 / (800 dt) = 6.25e-3 m/s.
  dem::EngineOptions options;
  scene.dt = 1e-5;
  dem::State result[2];
  std::int64_t first_contact[2] = {-1, -1};
  for (const int with_close : {0, 1}) {
    options.close_margin = with_close ? 0.05 : 0.0;
    dem::State st;
    // Slow (below the fast speed): 4e-3 m/s each, from 0.3 mm apart, inside the skin.
    demtest::add(st, {0, 0, 0}, {4e-3, 0, 0}, r);
    demtest::add(st, {2 * r + 3e-4, 0, 0}, {-4e-3, 0, 0}, r);
    for (int k = 0; k < 6; ++k) demtest::add(st, {k * 2.3 * r, 5 * r, 0}, {}, r);  // candidates, not close
    dem::Engine engine(scene, options);
    for (int k = 0; k < 5000 && first_contact[with_close] < 0; ++k) {
      engine.step(st);
      if (engine.contact_stats().particle_contacts > 0) first_contact[with_close] = k;
    }
    if (with_close) {
      EXPECT_GT(engine.close_builds(), 2);  // listed again on the way
      EXPECT_LE(engine.close_share(), 0.9);
    }
    result[with_close] = st;
  }
  ASSERT_GT(first_contact[0], 100);
  EXPECT_EQ(first_contact[0], first_contact[1]);
  EXPECT_EQ(dem::differing_arrays(result[0], result[1]), "");
}

}  // namespace
