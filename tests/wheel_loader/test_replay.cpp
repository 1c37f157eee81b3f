// The wheel loader replayed against recorded soil wrenches (docs/replay.md): a short
// co-simulation over LCM (cosim_master + wheel_loader_adapter + dem_service, 2000 spheres
// dropped in front of the machine, 0.6 s with the bucket entering the soil) is recorded with
// --record; the replay runs the loader alone (no DEM process) against the recorded wrenches and
// gives every recorded dataset of the run bit for bit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "../oscillator/replay_harness.hpp"

namespace {

using replay_harness::bit_identical;
using replay_harness::run_cosim_master;
using replay_harness::number;
using replay_harness::text;

constexpr const char* kConfig = "configs/wheel_loader.yaml";

std::vector<std::string> scenario() {
  const std::string mesh = std::string(BIN_DIR) + "/../meshes/bucket_r1.stl";
  return {"--set", "time.end=0.6",
          // the cutting edge starts 0.2 m before the soil (it reaches x = 6.65 m at t = 2 s from 0)
          "--set", "participants.loader.parameters={initial_position: 2.15}",
          // 2000 spheres dropped from random places in front of the back wall, not settled (the
          // test is about the replay; the soil only has to push back); one DEM thread.
          "--set",
          "participants.soil.launch=[dem_service, " + harness::source("configs/soil/pile.yaml") +
              ", --set, 'tools.0.mesh=" + mesh + "', --set, scene.threads=1, --set, "
              "'particles={fill: [{species: grain, min: [6.6, -1.9, 0], max: [8.4, 1.9, 1.2], count: 2000, seed: 5}]}']",
          "--set", "participants.soil.parameters={output.file: ''}"};
}

std::vector<std::string> with(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

}  // namespace

TEST(WheelLoaderReplay, TheLoaderAgainstRecordedSoilWrenchesIsBitIdenticalWithoutTheDem) {
  replay_harness::ScopedEnv file("COSIM_KEY_FILE", ""), key("COSIM_KEY", "");
  const std::string a = harness::temp_path("_recorded.h5"), log = harness::temp_path("_recorded.lcmlog");
  ASSERT_EQ(run_cosim_master(kConfig, a, with(scenario(), {"--record", log}), 300), 0) << harness::read_text(a + ".log");

  // The soil pushed back: the replay has real wrenches to play.
  const auto soil = harness::read_dataset(a, "participants/soil/outputs/bucket");  // 9 per row
  ASSERT_EQ(soil.size(), 9u * 601);
  int pushing = 0;
  double peak = 0;
  for (std::size_t row = 0; row < 601; ++row) {
    const double f = std::hypot(soil[9 * row], soil[9 * row + 1], soil[9 * row + 2]);
    pushing += f > 100 ? 1 : 0;
    peak = std::max(peak, f);
  }
  std::printf("soil force above 100 N in %d of 600 steps, peak %.0f N\n", pushing, peak);
  EXPECT_GT(pushing, 200);
  EXPECT_GT(peak, 5e3);

  const std::string b = harness::temp_path("_replay.h5");
  ASSERT_EQ(run_cosim_master(kConfig, b, with(scenario(), {"--replay", log, "--replay-side", "loader"}), 300), 0)
      << harness::read_text(b + ".log");
  const std::string blog = harness::read_text(b + ".log");
  EXPECT_NE(blog.find("replaying soil from " + log), std::string::npos) << blog;
  EXPECT_EQ(blog.find("dem_service"), std::string::npos) << "no DEM may run in the replay:\n" << blog;
  EXPECT_EQ(blog.find("soil: joined session"), std::string::npos) << blog;
  EXPECT_NE(blog.find("loader: joined session"), std::string::npos) << blog;
  for (const char* ds : {"time", "participants/loader/outputs/bucket", "participants/loader/outputs/a_long",
                         "participants/loader/outputs/a_vert", "participants/loader/outputs/j_long",
                         "participants/loader/outputs/j_vert", "participants/loader/outputs/speed",
                         "participants/soil/outputs/bucket", "connections/soil.bucket/sent",
                         "connections/loader.bucket_wrench/sent", "power/bucket/residual"}) {
    const auto x = harness::read_dataset(a, ds), y = harness::read_dataset(b, ds);
    EXPECT_GE(x.size(), 601u) << ds;
    EXPECT_TRUE(bit_identical(x, y)) << ds;
  }
  EXPECT_EQ(text(b, "status"), "finished");
  EXPECT_EQ(text(b, "replay/played"), "soil");
  EXPECT_EQ(text(b, "replay/live"), "loader");
  EXPECT_EQ(number(b, "replay/diverged"), 0);
  double requests = 0;  // one per step and iteration (start-up steps are done more than once)
  for (double n : harness::read_dataset(a, "timing/iterations")) requests += n;
  EXPECT_GE(requests, 600);
  EXPECT_EQ(number(b, "replay/requests_compared"), requests);
  double wall_a = 0, wall_b = 0;
  for (double w : harness::read_dataset(a, "timing/step_wall")) wall_a += w;
  for (double w : harness::read_dataset(b, "timing/step_wall")) wall_b += w;
  std::printf("steps' wall time: recorded run %.2f s, replay %.2f s\n", wall_a, wall_b);
}
