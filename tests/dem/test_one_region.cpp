// One parallel region per DEM step (EngineOptions::one_region, docs/performance.md "One parallel
// region per DEM step"): the pair blocks, the boundary contacts and the integration run in one
// OpenMP region instead of a region each (a boundary chunk waits for the pair blocks of its
// particles, or all wait at a barrier; a barrier before the integration). The work is split as
// before and every sum runs in the same order, so a run is the same bits as with a region per
// stage, on 1 and 2 threads, with and without sleepers, with the sleepers' awake list or the
// walk over every particle (close pairs), with a moving tool, and through a checkpoint; and a
// particle with too many boundary contacts stops the step before anything is advanced, as before.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>

#include "dem/checkpoint.hpp"
#include "dem_test_util.hpp"

namespace {

using demtest::Vec3;

// A polydisperse lattice of 3000 grains (21 layers of 12 x 12) with gaps inside the skin,
// creeping at up to 4 mm/s, one grain in 25 thrown through it at 0.5 m/s, on a floor, with a
// plate pushed into its side (x = 27 mm to 21 mm over the run): contacts begin and end, grains
// reach the floor and the plate, fall asleep and are woken by the thrown ones and the plate.
constexpr int kGrains = 3000;
constexpr int kSteps = 400;
constexpr double kDt = 2e-5;  // the dt of demtest::thrown_lattice_scene

dem::Scene lattice_scene(int threads, bool sleep) {
  dem::Scene scene = demtest::thrown_lattice_scene(threads);
  std::vector<Vec3> corners;
  demtest::quad(corners, {0, -0.005, -0.002}, {0, 0.03, -0.002}, {0, 0.03, 0.1}, {0, -0.005, 0.1});
  dem::Tool plate = demtest::static_tool("plate", corners);
  plate.motion.keyframes = {{0, {0.027, 0, 0}, {1, 0, 0, 0}},
                            {kSteps * kDt, {0.021, 0, 0}, {1, 0, 0, 0}}};
  dem::validate_keyframes(plate.motion.keyframes, "test");
  scene.tools.push_back(plate);
  if (sleep) {
    scene.sleep.enabled = true;
    scene.sleep.speed = 2e-2;  // the creeping grains fall asleep, the thrown ones wake them
    scene.sleep.steps = 20;
    scene.sleep.neighbourhood = dem::SleepNeighbourhood::box;
    scene.sleep.tool_distance = 1e-3;  // the plate wakes the grains it comes near
  }
  return scene;
}

dem::State lattice_state() { return demtest::thrown_lattice(kGrains); }

dem::EngineOptions options(bool one_region, double close_margin = 0.0) {
  dem::EngineOptions o;
  o.min_particles_per_thread = 100;  // every thread asked for
  o.one_region = one_region;
  o.close_margin = close_margin;
  return o;
}

bool same_bits(const Vec3& a, const Vec3& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// What a run gives, step by step.
struct RegionRun {
  dem::State state;
  std::vector<dem::Wrench> plate;  // the tool's wrench
  std::vector<Vec3> floor;         // the floor's force
  std::vector<std::int64_t> sleeping, contacts;
  std::int64_t one_region_steps = 0, woke = 0, fell = 0;
};

void step_and_record(const dem::Scene& scene, dem::Engine& e, RegionRun& r) {
  r.state.tool_pose[0] = scene.tools[0].motion.evaluate(r.state.step * scene.dt);
  e.step(r.state);
  r.plate.push_back(e.tool_wrenches()[0]);
  r.floor.push_back(e.wall_forces()[0]);
  r.sleeping.push_back(e.sleeping());
  r.contacts.push_back(e.contact_stats().particle_contacts + e.contact_stats().boundary_contacts);
}

RegionRun run(const dem::Scene& scene, const dem::EngineOptions& o) {
  RegionRun r;
  r.state = lattice_state();
  dem::Engine e(scene, o);
  for (int k = 0; k < kSteps; ++k) step_and_record(scene, e, r);
  r.one_region_steps = e.one_region_steps();
  r.woke = e.woke_total();
  r.fell = e.fell_asleep_total();
  return r;
}

// The first step whose recorded outputs differ, or -1.
int first_difference(const RegionRun& a, const RegionRun& b) {
  if (a.plate.size() != b.plate.size()) return 0;
  for (std::size_t k = 0; k < a.plate.size(); ++k)
    if (!same_bits(a.plate[k].force, b.plate[k].force) ||
        !same_bits(a.plate[k].torque, b.plate[k].torque) || !same_bits(a.floor[k], b.floor[k]) ||
        a.sleeping[k] != b.sleeping[k] || a.contacts[k] != b.contacts[k])
      return static_cast<int>(k);
  return -1;
}

// The paths both region tests run: all awake (the walk over every particle), sleeping (the
// awake list's integration), and sleeping with close pairs (the walk with the sleeping rules).
struct Case {
  const char* name;
  bool sleep;
  double close_margin;
};
constexpr Case kCases[] = {{"all awake", false, 0.0}, {"sleeping", true, 0.0},
                           {"sleeping, close pairs", true, 0.1}};

// One region against a region per stage, on 1 and 2 threads: all awake (the walk over every
// particle), sleeping (the awake list's integration), and sleeping with close pairs (the walk
// over every particle with the sleeping rules).
TEST(dem_OneRegion, SameBitsAsARegionPerStage) {
  for (const Case& c : kCases) {
    for (const int threads : {1, 2}) {
      dem::Scene scene = lattice_scene(threads, c.sleep);
      scene.sleep.close_pairs = c.close_margin > 0;
      const RegionRun stages = run(scene, options(false, c.close_margin));
      const RegionRun one = run(scene, options(true, c.close_margin));
      const std::string what = std::string(c.name) + ", " + std::to_string(threads) + " threads";
      EXPECT_EQ(stages.one_region_steps, 0) << what;
      EXPECT_EQ(one.one_region_steps, kSteps) << what;
      EXPECT_EQ(dem::differing_arrays(stages.state, one.state), "") << what;
      EXPECT_EQ(first_difference(stages, one), -1) << what;
      EXPECT_EQ(one.woke, stages.woke) << what;
      EXPECT_EQ(one.fell, stages.fell) << what;
      // The run means something: contacts with the plate and the floor, and with sleeping,
      // sleepers beside awake grains for most of it, woken and falling asleep.
      EXPECT_GT(std::abs(one.plate.back().force.x), 0.0) << what;
      EXPECT_GT(std::abs(one.floor.back().z), 0.0) << what;
      if (c.sleep) {
        std::int64_t mixed = 0;
        for (const std::int64_t n : one.sleeping) mixed += n > 0 && n < kGrains;
        EXPECT_GT(mixed, kSteps / 2) << what;
        EXPECT_GT(one.woke, 100) << what;
        EXPECT_GT(one.fell, 1000) << what;
        std::printf("%s: %lld steps with sleepers beside awake grains, woke %lld, fell asleep "
                    "%lld, %lld broad phases\n",
                    what.c_str(), static_cast<long long>(mixed), static_cast<long long>(one.woke),
                    static_cast<long long>(one.fell), static_cast<long long>(one.state.rebuilds));
      }
    }
  }
}

// The engine's own threads (scene.thread_wait: yield, dem/thread_team.hpp) run the same region
// as OpenMP's team: the same bits on 2 threads, all awake, sleeping, and sleeping with close
// pairs; one thread makes no team.
TEST(dem_OneRegion, OwnThreadsGiveTheBitsOfOpenMPs) {
  for (const Case& c : kCases) {
    for (const int threads : {1, 2}) {
      dem::Scene omp = lattice_scene(threads, c.sleep);
      omp.sleep.close_pairs = c.close_margin > 0;
      omp.thread_wait = dem::ThreadWait::passive;
      dem::Scene own = omp;
      own.thread_wait = dem::ThreadWait::yield;
      const RegionRun a = run(omp, options(true, c.close_margin));
      RegionRun b;
      b.state = lattice_state();
      dem::Engine e(own, options(true, c.close_margin));
      for (int k = 0; k < kSteps; ++k) step_and_record(own, e, b);
      const std::string what = std::string(c.name) + ", " + std::to_string(threads) + " threads";
      EXPECT_EQ(e.one_region_steps(), kSteps) << what;
      if (threads == 2) {
        ASSERT_NE(e.own_threads(), nullptr) << what;
        const dem::ThreadTeam::Waits w = e.own_threads()->waits();
        EXPECT_GT(w.awake + w.slept, kSteps) << what;  // at least each step's end was waited for
      } else {
        EXPECT_EQ(e.own_threads(), nullptr) << what;
      }
      EXPECT_EQ(dem::differing_arrays(a.state, b.state), "") << what;
      EXPECT_EQ(first_difference(a, b), -1) << what;
      EXPECT_EQ(e.woke_total(), a.woke) << what;
      EXPECT_EQ(e.fell_asleep_total(), a.fell) << what;
      if (c.sleep) {
        EXPECT_GT(a.woke, 100) << what;
      }
    }
  }
}

// Two threads in one region against one thread, through a checkpoint: the 2-thread run is saved
// half way and continued by a fresh engine from the file; every step's wrench, floor force and
// sleeper count, and the final state, are the 1-thread run's bits.
// Both with OpenMP's team and with the engine's own threads (scene.thread_wait: yield).
TEST(dem_OneRegion, TwoThreadsThroughACheckpointGiveTheBitsOfOne) {
  for (const dem::ThreadWait wait : {dem::ThreadWait::passive, dem::ThreadWait::yield})
  for (const bool sleep : {false, true}) {
    const std::string what = std::string(sleep ? "sleeping" : "all awake") + ", thread_wait " +
                             dem::thread_wait_name(wait);
    const dem::Scene one_scene = lattice_scene(1, sleep);
    dem::Scene two_scene = lattice_scene(2, sleep);
    two_scene.thread_wait = wait;
    const RegionRun one = run(one_scene, options(true));
    RegionRun two;
    two.state = lattice_state();
    {
      dem::Engine e(two_scene, options(true));
      for (int k = 0; k < kSteps / 2 + 3; ++k) step_and_record(two_scene, e, two);
      ASSERT_EQ(e.threads(), 2) << what;
      EXPECT_EQ(e.one_region_steps(), kSteps / 2 + 3) << what;
      EXPECT_EQ(e.own_threads() != nullptr, wait == dem::ThreadWait::yield) << what;
    }
    const std::string file = (std::filesystem::temp_directory_path() /
                              ("dem_one_region_" + std::to_string(sleep) +
                               dem::thread_wait_name(wait) + ".h5"))
                                 .string();
    dem::save_checkpoint(two.state, file);
    two.state = dem::load_checkpoint(file);
    std::filesystem::remove(file);
    dem::Engine e(two_scene, options(true));  // a fresh engine: nothing kept in its workspace
    while (two.plate.size() < static_cast<std::size_t>(kSteps)) step_and_record(two_scene, e, two);
    EXPECT_EQ(dem::differing_arrays(one.state, two.state), "") << what;
    EXPECT_EQ(first_difference(one, two), -1) << what;
    if (sleep) {
      EXPECT_GT(*std::max_element(one.sleeping.begin(), one.sleeping.end()), 500) << what;
    }
  }
}

// A particle touching more walls than it has boundary slots (kBoundarySlots) stops the step with
// the error that names it, before the integration: in one region as with a region per stage,
// no particle has moved when it is thrown, on 1 and 2 threads.
TEST(dem_OneRegion, TooManyBoundaryContactsStopTheStepBeforeAnythingMoves) {
  for (const int threads : {1, 2}) {
    for (const int variant : {0, 1, 2}) {  // a region per stage, one region, its own threads
      const bool one_region = variant > 0;
      // Two particles inside a cage of more walls than kBoundarySlots, each on a thread of its
      // own.
      auto [scene, st] = demtest::caged_pair_scene(threads);
      if (variant == 2) scene.thread_wait = dem::ThreadWait::yield;
      dem::EngineOptions o = options(one_region);
      o.min_particles_per_thread = 1;
      dem::Engine e(scene, o);
      e.prepare(st);
      const std::vector<Vec3> x = st.x, v = st.v;
      const std::int64_t step = st.step;
      std::string message;
      try {
        e.step(st);
      } catch (const dem::SimulationError& err) {
        message = err.what();
      }
      const std::string what = std::to_string(threads) + " threads, " +
                               (variant == 2   ? "one region on its own threads"
                                : one_region ? "one region"
                                             : "a region per stage");
      EXPECT_NE(message.find("particle id "), std::string::npos) << what << ": " << message;
      EXPECT_NE(message.find("touches more than 8 walls"), std::string::npos) << what << ": " << message;
      EXPECT_EQ(e.threads(), threads) << what;
      EXPECT_EQ(st.step, step) << what;
      EXPECT_EQ(std::memcmp(x.data(), st.x.data(), x.size() * sizeof(Vec3)), 0) << what;
      EXPECT_EQ(std::memcmp(v.data(), st.v.data(), v.size() * sizeof(Vec3)), 0) << what;
    }
  }
}

}  // namespace
