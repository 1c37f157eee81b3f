// Pair blocks (performance.pair_schedule: blocks): the threads take blocks of rows of the half list
// whose partners lie in the block or the next one; an odd block runs when the even blocks
// beside it are done. Each thread walks the blocks in its own order and runs those it claims
// first. Every sum is then made in an order that does not depend on the number of
// threads or on which thread took which block: a run is the same bit for bit on 1, 2 and 3
// threads, with either kernel, with close pairs and with sleepers, and so are the forces on
// walls and tools (summed per fixed chunk of particles, then in chunk order). Against the
// ranges schedule only the summation order differs, so the forces agree to rounding.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "dem_test_util.hpp"

namespace {

using demtest::Vec3;

// A polydisperse lattice of 6000 grains (42 layers of 12 x 12) with gaps inside the skin,
// creeping at up to 4 mm/s, and one grain in 25 thrown through it at 0.5 m/s, on a floor:
// collisions spread, friction holds springs, contacts end and begin, grains reach the floor.
// Its engine: 100 particles per thread are enough to use every thread asked for.
dem::EngineOptions blocks_options(double close_margin = 0.0) {
  dem::EngineOptions o;
  o.min_particles_per_thread = 100;
  o.close_margin = close_margin;
  return o;
}

dem::Scene blocks_scene(int threads) {
  dem::Scene scene = demtest::thrown_lattice_scene(threads);
  // A plate across the thrown grains' path (x = 27 mm), reached after about 200 steps.
  std::vector<Vec3> corners;
  demtest::quad(corners, {0.027, -0.005, -0.002}, {0.027, 0.03, -0.002}, {0.027, 0.03, 0.1},
                {0.027, -0.005, 0.1});
  scene.tools.push_back(demtest::static_tool("plate", corners));
  return scene;
}

dem::State blocks_state() { return demtest::thrown_lattice(6000); }

bool same_bits(const Vec3& a, const Vec3& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

struct BlockRun {
  dem::State state;
  std::vector<dem::Wrench> plate;  // the tool's wrench, every step
  std::vector<dem::Vec3> floor;    // the floor's force, every step
  std::size_t blocks = 0;
  std::int64_t contact_steps = 0, sleeper_steps = 0, tool_contact_steps = 0;
};

BlockRun run(dem::Scene scene, int steps,
             dem::EngineOptions::PairKernel kernel = dem::EngineOptions::PairKernel::vector,
             double close_margin = 0.0) {
  BlockRun r;
  r.state = blocks_state();
  r.state.tool_pose.resize(scene.tools.size());
  dem::EngineOptions options = blocks_options(close_margin);
  options.pair_kernel = kernel;
  dem::Engine engine(scene, options);
  for (int k = 0; k < steps; ++k) {
    engine.step(r.state);
    r.contact_steps += engine.contact_stats().particle_contacts;
    r.tool_contact_steps += engine.contact_stats().boundary_contacts;
    if (!scene.tools.empty()) r.plate.push_back(engine.tool_wrenches()[0]);
    r.floor.push_back(engine.wall_forces()[0]);
    r.sleeper_steps += engine.sleeping();
    if (!engine.pair_block_starts().empty())
      r.blocks = std::max(r.blocks, engine.pair_block_starts().size() - 1);
  }
  return r;
}

// The threads' walks: each visits every block once, and an odd block only after both even
// blocks beside it (so a thread waiting on them waits for blocks already claimed, which never
// wait themselves: no deadlock). On two threads one starts at the bottom and the other at the
// top; on T threads the first T - 1 start at about t K / T.
TEST(dem_PairBlocks, EveryWalkVisitsEachBlockOnceAndEvensFirst) {
  for (int T = 1; T <= 5; ++T)
    for (std::int32_t K = 1; K <= 41; ++K)
      for (int t = 0; t < T; ++t) {
        const std::vector<std::int32_t> w = dem::detail::pair_block_walk(K, t, T);
        ASSERT_EQ(static_cast<std::int32_t>(w.size()), K) << "K " << K << " t " << t << " T " << T;
        std::vector<int> at(K, -1);
        for (std::size_t p = 0; p < w.size(); ++p) {
          ASSERT_GE(w[p], 0);
          ASSERT_LT(w[p], K);
          ASSERT_EQ(at[w[p]], -1) << "block " << w[p] << " twice (K " << K << " t " << t << ")";
          at[w[p]] = static_cast<int>(p);
        }
        for (std::int32_t k = 1; k < K; k += 2) {
          EXPECT_LT(at[k - 1], at[k]) << "K " << K << " t " << t << " T " << T << " block " << k;
          if (k + 1 < K) {
            EXPECT_LT(at[k + 1], at[k]) << "K " << K << " t " << t << " T " << T << " block " << k;
          }
        }
        if (T >= 2 && t == T - 1) {
          EXPECT_EQ(w[0], (K - 1) / 2 * 2);  // the top even block
        } else {
          EXPECT_EQ(w[0], static_cast<std::int32_t>(static_cast<std::int64_t>(K) * t / T) / 2 * 2);
        }
      }
}

// The construction: every partner of block k's rows lies in block k or k + 1, the blocks
// cover the rows in order, and there are enough of them to share between threads.
TEST(dem_PairBlocks, EveryPartnerInItsBlockOrTheNext) {
  const dem::Scene scene = blocks_scene(2);
  dem::State st = blocks_state();
  dem::Engine engine(scene, blocks_options());
  for (int k = 0; k < 50; ++k) engine.step(st);
  const std::vector<std::size_t>& b = engine.pair_block_starts();
  ASSERT_GE(b.size(), 7u);  // at least 6 blocks for 6000 grains
  EXPECT_EQ(b.front(), 0u);
  EXPECT_EQ(b.back(), st.size());
  std::size_t pairs = 0;
  for (std::size_t k = 0; k + 1 < b.size(); ++k) {
    ASSERT_LT(b[k], b[k + 1]);
    const std::size_t limit = b[std::min(k + 2, b.size() - 1)];
    for (std::size_t i = b[k]; i < b[k + 1]; ++i)
      for (std::int32_t q = st.pair_offset[i]; q < st.pair_offset[i + 1]; ++q) {
        ++pairs;
        ASSERT_LT(static_cast<std::size_t>(st.pair_j[q]), limit) << "block " << k << " row " << i;
      }
  }
  EXPECT_EQ(pairs, st.pair_j.size());
}

TEST(dem_PairBlocks, SameBitsOnOneTwoAndThreeThreads) {
  for (const dem::EngineOptions::PairKernel kernel : demtest::pair_kernels()) {
    for (const double margin : {0.0, 0.1}) {
      BlockRun one;
      for (const int threads : {1, 2, 3}) {
        dem::Scene scene = blocks_scene(threads);
        BlockRun r = run(scene, 400, kernel, margin);
        EXPECT_GE(r.blocks, 6u);
        EXPECT_GT(r.contact_steps, 40000);  // about 160 touching pairs per step
        EXPECT_GT(r.tool_contact_steps, 1000);  // floor and plate contacts
        EXPECT_GT(std::abs(r.plate.back().force.x), 0.0);  // the plate is hit
        if (threads == 1) {
          one = std::move(r);
          continue;
        }
        EXPECT_EQ(dem::differing_arrays(one.state, r.state), "")
            << threads << " threads against 1, margin " << margin << ", "
            << demtest::kernel_name(kernel) << " kernel";
        // The forces on the plate and the floor, every step: summed per chunk, then in order.
        ASSERT_EQ(r.plate.size(), one.plate.size());
        for (std::size_t k = 0; k < r.plate.size(); ++k) {
          EXPECT_TRUE(same_bits(r.plate[k].force, one.plate[k].force) &&
                      same_bits(r.plate[k].torque, one.plate[k].torque) &&
                      same_bits(r.floor[k], one.floor[k]))
              << "step " << k << ", " << threads << " threads";
        }
      }
    }
  }
}

TEST(dem_PairBlocks, SameBitsOnOneAndTwoThreadsWithSleepers) {
  for (const dem::EngineOptions::PairKernel kernel : demtest::pair_kernels()) {
    BlockRun r[2];
    for (const int threads : {1, 2}) {
      dem::Scene scene = blocks_scene(threads);
      scene.sleep.enabled = true;
      scene.sleep.speed = 2e-2;  // the creeping grains fall asleep, the thrown ones wake them
      scene.sleep.steps = 20;
      scene.sleep.tool_distance = 0;
      scene.tools.clear();  // its neighbourhood would keep the lattice awake
      r[threads - 1] = run(scene, 400, kernel);
    }
    EXPECT_GT(r[0].sleeper_steps, 100000);
    EXPECT_EQ(dem::differing_arrays(r[0].state, r[1].state), "")
        << demtest::kernel_name(kernel) << " kernel";
  }
}

// Blocks against ranges: the same pairs, summed in another order. After one step from the same
// state every velocity agrees to rounding (a lost or doubled pair force would be off by the
// force of a contact, about 1e-3 of the velocities' scale).
TEST(dem_PairBlocks, RangesGiveTheSameForcesToRounding) {
  dem::State st[2];
  for (const int schedule : {0, 1}) {
    dem::Scene scene = blocks_scene(2);
    dem::EngineOptions options = blocks_options();
    options.pair_schedule = schedule ? dem::PairSchedule::ranges : dem::PairSchedule::blocks;
    st[schedule] = blocks_state();
    dem::Engine engine(scene, options);
    for (int k = 0; k < 20; ++k) engine.step(st[schedule]);  // collisions under way
  }
  ASSERT_EQ(st[0].size(), st[1].size());
  double scale = 0, worst = 0;
  for (std::size_t i = 0; i < st[0].size(); ++i) {
    scale = std::max(scale, dem::norm(st[0].u[i]));
    worst = std::max(worst, dem::norm(st[0].u[i] - st[1].u[i]));
  }
  EXPECT_GT(scale, 0.1);
  EXPECT_LT(worst, 1e-10 * scale);
  // The order did change: the two schedules are not one code path.
  EXPECT_NE(dem::differing_arrays(st[0], st[1]), "");
}

// Engine::thread_busy: each thread's working time in the three parallel sections is counted,
// is positive for both threads and is no more than the section's wall time (it is timed inside
// the section; waits left out). How much of the wall time it is depends on the machine's load,
// so that is not asserted. reset_thread_busy() zeroes it.
TEST(dem_PairBlocks, ThreadBusyTimeIsCountedPerThread) {
  const dem::Scene scene = blocks_scene(2);
  dem::State st = blocks_state();
  dem::Engine engine(scene, blocks_options());
  for (int k = 0; k < 300; ++k) engine.step(st);
  ASSERT_EQ(engine.threads(), 2);
  for (const std::size_t sec :
       {dem::section::pair_forces, dem::section::mesh_contacts, dem::section::integration}) {
    const double wall = engine.timing().seconds(sec);
    for (int t = 0; t < 2; ++t) {
      const double b = engine.thread_busy(sec, t);
      EXPECT_GT(b, 0) << engine.timing().name(sec) << ", thread " << t;
      EXPECT_LE(b, wall * 1.05 + 1e-4) << engine.timing().name(sec) << ", thread " << t;
    }
  }
  engine.reset_thread_busy();
  for (int t = 0; t < 2; ++t) EXPECT_EQ(engine.thread_busy(dem::section::pair_forces, t), 0);
}

}  // namespace
