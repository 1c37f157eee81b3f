// Co-simulations across three network namespaces (hosts) joined through a fourth (the switch)
// where netns_relay loses, duplicates, reorders and delays frames (tests/netns/rig.sh): the
// master in one namespace, each participant started by hand in another, bus URL with ttl=1.
// Each run must finish and record bit-identically what the lossless run records. Wall times
// and ratios are printed, not asserted (bench/bus/netns_loss.sh is the timed comparison).
// Root only: elsewhere every test is skipped with the reason.
#include <signal.h>
#include <sys/wait.h>

#include <cstdio>
#include <cmath>
#include <cstring>
#include <memory>
#include <regex>

#include "harness.hpp"

namespace {

const std::string kUrl = "udpm://239.255.76.67:7667?ttl=1";

int shell(const std::string& command, std::string* output = nullptr) {
  FILE* p = popen((command + " 2>&1").c_str(), "r");
  if (!p) return -1;
  char buf[512];
  std::string out;
  while (std::fgets(buf, sizeof buf, p)) out += buf;
  const int status = pclose(p);
  if (output) *output = out;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string rig(const std::string& args) { return "bash " + harness::source("tests/netns/rig.sh") + " " + args; }

bool bit_identical(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

struct Impairment {
  double loss = 0, dup = 0, reorder = 0, delay = 0.001;
  std::string spec() const {
    char buf[160];
    std::snprintf(buf, sizeof buf, "loss=%g,dup=%g,reorder=%g,delay=%g", loss, dup, reorder, delay);
    return buf;
  }
};

struct RunResult {
  int code = -1;
  double wall = 0;
  std::string h5, log;
};

class Rig : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::string why;
    if (shell(rig("check"), &why) != 0) {
      reason_ = why.empty() ? "rig.sh check failed" : why.substr(0, why.find('\n'));
      return;
    }
    prefix_ = "ct" + std::to_string(getpid() % 100000);
    shell(rig("down " + prefix_));
    std::string out;
    if (shell(rig("up " + prefix_), &out) != 0) {
      reason_ = "rig.sh up failed: " + out;
      shell(rig("down " + prefix_));
      return;
    }
    up_ = true;
  }
  static void TearDownTestSuite() {
    if (up_) shell(rig("down " + prefix_));
    up_ = false;
  }
  void SetUp() override {
    if (!up_) GTEST_SKIP() << "netns rig skipped: " << reason_;
  }

  static std::vector<std::string> in(const std::string& host, std::vector<std::string> args) {
    args.insert(args.begin(), {"/usr/sbin/ip", "netns", "exec", prefix_ + host});
    return args;
  }

  // Starts the relay with `imp` on every link, the participants (each with its own host), and
  // the master on host a; returns when the master is done.
  RunResult run(const Impairment& imp, const std::string& tag, const std::string& config,
          const std::vector<std::pair<std::string, std::vector<std::string>>>& participants,
          const std::vector<std::string>& overrides, const std::string& extra_c = "") {
    RunResult r;
    r.h5 = harness::temp_path("_" + tag + ".h5");
    std::remove(r.h5.c_str());
    const std::string spec = imp.spec();
    auto relay = harness::spawn(in("sw", {harness::bin("netns_relay"), "--seed", "1", prefix_ + "a1:" + spec,
                                          prefix_ + "b1:" + spec,
                                          prefix_ + "c1:" + spec + (extra_c.empty() ? "" : "," + extra_c)}),
                                r.h5 + ".relay.log");
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    std::vector<harness::Process> parts;
    const char* hosts[] = {"b", "c"};
    for (std::size_t i = 0; i < participants.size(); ++i) {
      auto args = participants[i].second;
      args.insert(args.end(), {"--bus", kUrl, "--wait", "60"});
      parts.push_back(harness::spawn(in(hosts[i % 2], args), r.h5 + "." + participants[i].first + ".log"));
    }
    std::vector<std::string> args{harness::bin("cosim_master"), harness::source(config), "--output", r.h5,
                                  "--set", "bus.url=" + kUrl, "--set", "output.csv=", "--set",
                                  "output.progress=off", "--set", "bus.authenticate=false"};
    for (const auto& p : participants) args.insert(args.end(), {"--set", "participants." + p.first + ".launch=null"});
    for (const auto& o : overrides) args.insert(args.end(), {"--set", o});
    const cosim::Stopwatch wall;
    auto master = harness::spawn(in("a", args), r.h5 + ".log");
    r.code = harness::wait_for(master, 280);
    r.wall = wall.seconds();
    for (auto& p : parts) {
      if (harness::wait_for(p, 10) < 0) ADD_FAILURE() << "a participant did not leave at the end";
    }
    kill(relay.pid, SIGTERM);
    harness::wait_for(relay, 5);
    r.log = harness::read_text(r.h5 + ".log") + harness::read_text(r.h5 + ".relay.log");
    return r;
  }

  RunResult oscillator(const Impairment& imp, const std::string& tag, const std::vector<std::string>& overrides = {}) {
    return run(imp, tag, "configs/oscillator.yaml",
               {{"mass1", {harness::bin("oscillator_adapter"), "--side", "mass1"}},
                {"mass2", {harness::bin("oscillator_adapter"), "--side", "mass2"}}},
               overrides);
  }

  static double resends(const RunResult& r) {
    const auto v = harness::read_dataset(r.h5, "bus/resends");
    return v.empty() ? -1 : v[0];
  }

  // Frames the relay dropped on purpose, summed over the links ("dropped N" in its exit lines).
  static long relay_dropped(const RunResult& r) {
    long sum = 0;
    const std::regex re(", dropped ([0-9]+),");
    for (auto it = std::sregex_iterator(r.log.begin(), r.log.end(), re); it != std::sregex_iterator(); ++it)
      sum += std::stol((*it)[1]);
    return sum;
  }

  static void expect_identical(const RunResult& a, const RunResult& b, const std::vector<std::string>& datasets) {
    for (const auto& name : datasets) {
      const auto da = harness::read_dataset(a.h5, name), db = harness::read_dataset(b.h5, name);
      ASSERT_FALSE(da.empty()) << name;
      EXPECT_TRUE(bit_identical(da, db)) << name;
    }
    EXPECT_EQ(harness::read_string(b.h5, "status"), "finished");
  }

  static std::string prefix_, reason_;
  static bool up_;
};

std::string Rig::prefix_, Rig::reason_;
bool Rig::up_ = false;

const std::vector<std::string> kOscillatorData{
    "time", "participants/mass1/outputs/x", "participants/mass1/outputs/v", "participants/mass2/outputs/force",
    "connections/mass2.x/sent", "connections/mass1.force/sent", "connections/mass1.force/predicted",
    "power/coupling/energy_residual", "timing/iterations"};

}  // namespace

TEST_F(Rig, OscillatorAtFivePercentLossIsBitIdenticalToTheLosslessRun) {
  const RunResult clean = oscillator({}, "clean");
  ASSERT_EQ(clean.code, 0) << clean.log;
  const RunResult lossy = oscillator({0.05, 0.01, 0.05, 0.001}, "loss5");
  ASSERT_EQ(lossy.code, 0) << lossy.log;
  expect_identical(clean, lossy, kOscillatorData);
  // the relay really lost messages (most cost nothing: their redundant copy arrived)
  EXPECT_GT(relay_dropped(lossy), 0) << lossy.log;
  // and it equals the schedule run in one process
  const auto s = harness::run_in_process(harness::oscillator_config({"output.file=", "output.csv="}));
  EXPECT_TRUE(bit_identical(harness::read_dataset(lossy.h5, "participants/mass2/outputs/force"), s.force));
  std::printf("oscillator, 1 ms delay per link: lossless %.2f s; 5 %% loss, 1 %% dup, 5 %% reorder %.2f s "
              "(ratio %.2f), %.0f resends\n",
              clean.wall, lossy.wall, lossy.wall / clean.wall, resends(lossy));
}

// 20 % loss on every link: more than a third of the round trips fail. A quarter of the run
// (500 macro steps) keeps the test short; bench/bus/netns_loss.sh runs the whole second.
TEST_F(Rig, OscillatorAtTwentyPercentLossCompletesIdentical) {
  const std::vector<std::string> quarter{"time.end=0.25"};
  const RunResult lossy = oscillator({0.20, 0.01, 0.05, 0.001}, "loss20", quarter);
  ASSERT_EQ(lossy.code, 0) << lossy.log;
  EXPECT_GT(resends(lossy), 0) << lossy.log;
  const auto s = harness::run_in_process(harness::oscillator_config({"time.end=0.25", "output.file=", "output.csv="}));
  ASSERT_EQ(s.x1.size(), 501u);
  EXPECT_TRUE(bit_identical(harness::read_dataset(lossy.h5, "participants/mass1/outputs/x"), s.x1));
  EXPECT_TRUE(bit_identical(harness::read_dataset(lossy.h5, "participants/mass1/outputs/v"), s.v1));
  EXPECT_TRUE(bit_identical(harness::read_dataset(lossy.h5, "participants/mass2/outputs/force"), s.force));
  EXPECT_EQ(harness::read_string(lossy.h5, "status"), "finished");
  std::printf("oscillator to t = 0.25 s at 20 %% loss: %.2f s, %.0f resends\n", lossy.wall, resends(lossy));
}

// The DEM service (1500 spheres, a blade pushed through them) and the prescribed blade on two
// hosts, 5 % loss: the same wrenches and poses as without loss.
TEST_F(Rig, DemCoSimulationAtFivePercentLossIsIdentical) {
  const std::vector<std::string> overrides{"time.end=0.015", "time.macro_step=2e-5"};
  const std::vector<std::pair<std::string, std::vector<std::string>>> parts{
      {"dem", {harness::bin("dem_service"), harness::source("tests/dem_service/scene.yaml"), "--name", "dem"}},
      {"tool", {harness::bin("prescribed_adapter"), "--name", "tool"}}};
  const RunResult clean = run({}, "dem_clean", "tests/dem_service/cosim.yaml", parts, overrides);
  ASSERT_EQ(clean.code, 0) << clean.log;
  const RunResult lossy = run({0.05, 0.01, 0.05, 0.001}, "dem_loss5", "tests/dem_service/cosim.yaml", parts, overrides);
  ASSERT_EQ(lossy.code, 0) << lossy.log;
  expect_identical(clean, lossy, {"time", "participants/dem/outputs/blade", "participants/tool/outputs/blade"});
  EXPECT_GT(relay_dropped(lossy), 0) << lossy.log;
  const auto w = harness::read_dataset(lossy.h5, "participants/dem/outputs/blade");
  double peak = 0;
  for (std::size_t i = 0; i < w.size(); i += 9) peak = std::max(peak, std::abs(w[i]) + std::abs(w[i + 2]));
  EXPECT_GT(peak, 100.0) << "the blade must meet the bed";
  std::printf("DEM co-simulation, 750 macro steps: lossless %.2f s, 5 %% loss %.2f s (ratio %.2f), %.0f resends\n",
              clean.wall, lossy.wall, lossy.wall / clean.wall, resends(lossy));
}

// A message too large for one datagram that loses one fragment (docs/protocol.md, "Messages
// larger than a datagram"). The blade's trajectory as 1200 inline keyframes makes the tool's
// configure about 90 KB: LCM sends it as two LC03 fragments, each a UDP datagram of up to 65 KB
// that IP splits into about 45 frames. The relay loses one frame of the first such datagram
// on its way to the tool's host: the kernel cannot reassemble that datagram, LCM drops the
// whole message, the master sends the configure again 0.5 s later, and the run is identical
// to the one without the loss.
TEST_F(Rig, LargeConfigureLosingOneFragmentIsSentAgainAndTheRunIsIdentical) {
  std::string keyframes;
  char kf[200];
  for (int i = 0; i <= 1200; ++i) {  // the first segment of blade_motion.csv, resampled
    const double s = i / 1200.0;
    const double qw = 1 + s * (0.9962 - 1), qy = s * 0.0872, n = std::sqrt(qw * qw + qy * qy);
    std::snprintf(kf, sizeof kf, "%s{time: %.6g, position: [%.6g, 0.05, %.6g], orientation: [%.6g, 0, %.6g, 0]}",
                  i ? ", " : "", 0.03 * s, 0.03 + 0.02 * s, 0.20 - 0.12 * s, qw / n, qy / n);
    keyframes += kf;
  }
  const std::string params = "participants.tool.parameters={tools: [{name: blade, interpolation: linear, keyframes: [" +
                             keyframes + "]}]}";
  ASSERT_GT(params.size(), 70000u) << "the configure must need more than one LCM datagram (65499 bytes)";
  const std::vector<std::string> overrides{"time.end=0.004", "time.macro_step=2e-5", params};
  const std::vector<std::pair<std::string, std::vector<std::string>>> parts{
      {"dem", {harness::bin("dem_service"), harness::source("tests/dem_service/scene.yaml"), "--name", "dem"}},
      {"tool", {harness::bin("prescribed_adapter"), "--name", "tool"}}};  // on host c
  const RunResult clean = run({}, "fragment_clean", "tests/dem_service/cosim.yaml", parts, overrides);
  ASSERT_EQ(clean.code, 0) << clean.log;
  const RunResult lost = run({}, "fragment_lost", "tests/dem_service/cosim.yaml", parts, overrides, "drop_fragment=1");
  ASSERT_EQ(lost.code, 0) << lost.log;
  EXPECT_NE(lost.log.find("c1: received"), std::string::npos) << lost.log;
  EXPECT_NE(lost.log.find("fragments dropped 1\n"), std::string::npos) << "the relay lost no fragment:\n" << lost.log;
  const auto sends = [](const RunResult& r) {
    const auto v = harness::read_dataset(r.h5, "participants/tool/bus/configure_sends");
    return v.empty() ? -1.0 : v[0];
  };
  EXPECT_EQ(sends(clean), 1) << clean.log;
  EXPECT_GE(sends(lost), 2) << lost.log;
  EXPECT_NE(lost.log.find("the configuration of 'tool' went out"), std::string::npos) << lost.log;
  expect_identical(clean, lost, {"time", "participants/dem/outputs/blade", "participants/tool/outputs/blade",
                                 "connections/dem.blade/sent", "connections/tool.blade_wrench/received"});
  std::printf("configure of about %zu KB: sent %.0f time(s) without loss, %.0f with one fragment lost\n",
              params.size() / 1000, sends(clean), sends(lost));
}
