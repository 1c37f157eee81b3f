// The wheel loader replayed against recorded soil wrenches (docs/replay.md): a short
// co-simulation over LCM (cosim_master + wheel_loader_adapter + dem_service, 1900 spheres
// dropped in front of the machine, 0.6 s with the bucket entering the soil) is recorded with
// --record; the replay runs the loader alone (no DEM process) against the recorded wrenches and
// gives every recorded dataset of the run bit for bit. With the tilt cylinder moved from
// t = 0.3 s on, the replay goes on and reports the step where the request to the soil first
// differs from the recorded one, the same step as a live run with that change.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>

#include "../oscillator/replay_harness.hpp"

namespace {

using replay_harness::bit_identical;
using replay_harness::run_cosim_master;
using replay_harness::number;
using replay_harness::text;

constexpr const char* kConfig = "configs/wheel_loader.yaml";

// loader_parameters: the loader's participants.loader.parameters beyond initial_position.
std::vector<std::string> scenario(const std::string& loader_parameters = "") {
  const std::string mesh = std::string(BIN_DIR) + "/../meshes/bucket_r1.stl";
  return {"--set", "time.end=0.6",
          // the cutting edge starts 0.2 m before the soil (it reaches x = 6.65 m at t = 2 s from 0)
          "--set", "participants.loader.parameters={initial_position: 2.15" + loader_parameters + "}",
          // 1900 spheres dropped from random places in front of the back wall, not settled (the
          // test is about the replay; the soil only has to push back); one DEM thread.
          "--set",
          "participants.soil.launch=[dem_service, " + harness::source("configs/soil/pile.yaml") +
              ", --set, 'tools.0.mesh=" + mesh + "', --set, scene.threads=1, --set, "
              "'particles={fill: [{species: grain, min: [6.6, -1.9, 0], max: [8.4, 1.9, 1.6], count: 1900, seed: 5}]}']",
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

TEST(WheelLoaderReplay, AChangedManeuverDivergesWhereTheChangeActs) {
  replay_harness::ScopedEnv file("COSIM_KEY_FILE", ""), key("COSIM_KEY", "");
  const std::string a = harness::temp_path("_recorded.h5"), log = harness::temp_path("_recorded.lcmlog");
  ASSERT_EQ(run_cosim_master(kConfig, a, with(scenario(), {"--record", log}), 300), 0) << harness::read_text(a + ".log");
  // The recorded tilt stays 0 until t = 2 s; this one starts to curl the bucket at 0.3 s.
  const std::string tilt = ", maneuver.tilt: [[0, 0.0], [0.3, 0.0], [0.6, 0.05]]";
  const std::string live = harness::temp_path("_live_tilt.h5");
  ASSERT_EQ(run_cosim_master(kConfig, live, scenario(tilt), 300), 0) << harness::read_text(live + ".log");
  const auto x = harness::read_dataset(a, "connections/soil.bucket/sent");
  const auto y = harness::read_dataset(live, "connections/soil.bucket/sent");
  ASSERT_EQ(x.size(), y.size());
  const std::size_t width = x.size() / 601;
  int64_t expected = -1;
  for (std::size_t row = 1; row <= 600 && expected < 0; ++row)
    if (std::memcmp(&x[row * width], &y[row * width], width * sizeof(double)) != 0)
      expected = static_cast<int64_t>(row) - 1;
  std::printf("a live run with the changed tilt first sends the soil other inputs at step %lld\n",
              static_cast<long long>(expected));
  ASSERT_GE(expected, 300);  // nothing changes before t = 0.3 s
  ASSERT_LE(expected, 302);

  const std::string r = harness::temp_path("_replay_tilt.h5");
  ASSERT_EQ(run_cosim_master(kConfig, r, with(scenario(tilt), {"--replay", log, "--replay-side", "loader"}), 300), 0)
      << harness::read_text(r + ".log");
  EXPECT_EQ(text(r, "status"), "finished");
  EXPECT_EQ(harness::read_dataset(r, "time").size(), 601u);
  EXPECT_EQ(number(r, "replay/diverged"), 1);
  EXPECT_EQ(number(r, "replay/diverged_at_step"), expected);
  EXPECT_NE(harness::read_text(r + ".log").find("diverged from the recording at step " + std::to_string(expected) + " "),
            std::string::npos)
      << harness::read_text(r + ".log");
  // The loader's own outputs change one step earlier: the request goes out with its outputs.
  EXPECT_EQ(number(r, "replay/outputs_differ_at_step"), expected - 1);
  // Up to there the replay and the live run with the change agree bit for bit.
  const auto bucket_live = harness::read_dataset(live, "participants/loader/outputs/bucket");
  const auto bucket_rep = harness::read_dataset(r, "participants/loader/outputs/bucket");
  ASSERT_EQ(bucket_live.size(), bucket_rep.size());
  EXPECT_EQ(std::memcmp(bucket_live.data(), bucket_rep.data(), 13 * (expected + 1) * sizeof(double)), 0);
}
