// The DEM step's own threads (dem/thread_team.hpp, scene.thread_wait: yield): every thread runs
// the function once per run, a barrier holds every thread until all have written, a worker that
// slept (no run for longer than it yields) is woken by the next run, and an exception on any
// thread reaches the caller.
#include <gtest/gtest.h>
#include <sched.h>

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

#include "dem/thread_team.hpp"

namespace {

TEST(dem_ThreadTeam, EveryThreadRunsOncePerRunAndBarriersHold) {
  for (const int T : {1, 2, 3}) {
    dem::ThreadTeam team(T);
    ASSERT_EQ(team.size(), T);
    std::vector<int> slot(static_cast<std::size_t>(T), -1);
    std::vector<int> calls(static_cast<std::size_t>(T), 0);
    long bad = 0;
    std::atomic<long> bad_reads{0};
    for (int run = 0; run < 2000; ++run) {
      auto fn = [&](int t) {
        ++calls[static_cast<std::size_t>(t)];
        slot[static_cast<std::size_t>(t)] = run;
        team.barrier(t);
        // Every thread has written this run's value before any passes the barrier.
        for (int u = 0; u < T; ++u)
          if (slot[static_cast<std::size_t>(u)] != run) bad_reads.fetch_add(1);
        team.barrier(t);  // nobody writes the next run's value while another still reads
      };
      team.run(fn);
      for (int u = 0; u < T; ++u) bad += slot[static_cast<std::size_t>(u)] != run;
    }
    EXPECT_EQ(bad, 0) << T << " threads";
    EXPECT_EQ(bad_reads.load(), 0) << T << " threads";
    for (int u = 0; u < T; ++u) EXPECT_EQ(calls[static_cast<std::size_t>(u)], 2000) << T << " threads";
  }
}

TEST(dem_ThreadTeam, ASleepingWorkerIsWokenByTheNextRun) {
  dem::ThreadTeam team(2);
  std::atomic<int> ran{0};
  auto fn = [&](int) { ran.fetch_add(1); };
  team.run(fn);
  // Longer than a worker yields: it sleeps, and the next run must wake it.
  std::this_thread::sleep_for(dem::ThreadTeam::kYieldFor * 20);
  team.run(fn);
  EXPECT_EQ(ran.load(), 4);
  EXPECT_GE(team.waits().slept, 1);
  // And the caller sleeps while a worker takes longer than it yields.
  auto slow = [&](int t) {
    if (t == 1) std::this_thread::sleep_for(dem::ThreadTeam::kYieldFor * 20);
    ran.fetch_add(1);
  };
  const std::int64_t slept = team.waits().slept;
  team.run(slow);
  EXPECT_EQ(ran.load(), 6);
  EXPECT_GT(team.waits().slept, slept);
}

TEST(dem_ThreadTeam, AnExceptionOnAnyThreadReachesTheCaller) {
  dem::ThreadTeam team(2);
  for (const int thrower : {0, 1}) {
    auto fn = [&](int t) {
      if (t == thrower) throw std::runtime_error("thread " + std::to_string(t) + " failed");
    };
    try {
      team.run(fn);
      ADD_FAILURE() << "no exception from thread " << thrower;
    } catch (const std::runtime_error& e) {
      EXPECT_EQ(std::string(e.what()), "thread " + std::to_string(thrower) + " failed");
    }
  }
  // A thread that fails before a barrier does not leave the others waiting there.
  for (const int thrower : {0, 1}) {
    int after_barrier = 0;
    auto fn = [&](int t) {
      if (t == thrower) throw std::runtime_error("failed before the barrier");
      team.barrier(t);
      ++after_barrier;
    };
    EXPECT_THROW(team.run(fn), std::runtime_error) << "thrower " << thrower;
    EXPECT_EQ(after_barrier, 0) << "thrower " << thrower;
  }
  // The team still works afterwards, barriers included.
  std::atomic<int> ran{0};
  auto fn = [&](int t) {
    team.barrier(t);
    ran.fetch_add(1);
    team.barrier(t);
  };
  team.run(fn);
  EXPECT_EQ(ran.load(), 2);
  EXPECT_THROW(dem::ThreadTeam(0), std::invalid_argument);
}

// A worker runs on the CPUs it was given (as the engine gives it those of OpenMP's thread of its
// number under OMP_PROC_BIND), and without a list keeps the caller's.
TEST(dem_ThreadTeam, WorkersRunOnTheCpusTheyWereGiven) {
  cpu_set_t mine;
  CPU_ZERO(&mine);
  ASSERT_EQ(::sched_getaffinity(0, sizeof mine, &mine), 0);
  std::vector<int> allowed;
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &mine)) allowed.push_back(c);
  ASSERT_FALSE(allowed.empty());
  const int last = allowed.back();
  std::vector<std::vector<int>> seen(2);
  auto record = [&](int t) {
    cpu_set_t set;
    CPU_ZERO(&set);
    ::sched_getaffinity(0, sizeof set, &set);
    for (int c = 0; c < CPU_SETSIZE; ++c)
      if (CPU_ISSET(c, &set)) seen[static_cast<std::size_t>(t)].push_back(c);
  };
  {
    dem::ThreadTeam team(2, {{}, {last}});
    team.run(record);
    EXPECT_EQ(seen[1], std::vector<int>{last});
    EXPECT_EQ(seen[0], allowed);  // the caller is not moved
  }
  seen.assign(2, {});
  dem::ThreadTeam team(2);
  team.run(record);
  EXPECT_EQ(seen[1], allowed);
}

}  // namespace
