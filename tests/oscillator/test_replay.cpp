// Recording the bus and replaying one side (docs/replay.md), on the oscillator over LCM:
// * `cosim_master --record` writes LCM's log format (read back here with LCM's own reader);
//   replaying mass1 live against the recorded mass2 (and the other way round) gives every
//   recorded dataset bit for bit, mass2 not running; so does a log taken by lcm-logger on the
//   bus (the way to record from any host);
// * with a changed mass1 parameter the run goes on and reports the step where the request to
//   mass2 first differs from the recorded one, checked against two independent live runs;
// * a log of another session, a truncated one (inside an event, and at an event boundary), a
//   changed one, one without the played participant and a file that is no log are refused
//   with messages that say so;
// * a keyed run's log needs the key to be replayed, is refused with another key, and replays
//   bit for bit with it.
#include <signal.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "replay_harness.hpp"

namespace {

using replay_harness::bit_identical;
using replay_harness::run_cosim_master;
using replay_harness::number;
using replay_harness::ScopedEnv;
using replay_harness::text;

constexpr const char* kConfig = "configs/oscillator.yaml";
constexpr int kSteps = 500;
const std::string kEnd = "time.end=0.25";  // 500 macro steps of 0.5 ms

const std::vector<std::string> kDatasets{"time",
                                         "participants/mass1/outputs/x",
                                         "participants/mass1/outputs/v",
                                         "participants/mass2/outputs/force",
                                         "connections/mass2.x/sent",
                                         "connections/mass2.v/sent",
                                         "connections/mass1.force/sent",
                                         "connections/mass1.force/received",
                                         "connections/mass2.x/predicted",
                                         "power/coupling/residual"};

void expect_bit_identical(const std::string& a, const std::string& b) {
  for (const auto& ds : kDatasets) {
    const auto x = harness::read_dataset(a, ds), y = harness::read_dataset(b, ds);
    EXPECT_GT(x.size(), static_cast<std::size_t>(kSteps)) << ds << " in " << a;
    EXPECT_TRUE(bit_identical(x, y)) << ds << ": " << a << " vs " << b;
  }
}

std::string log_of(const std::string& h5) { return harness::read_text(h5 + ".log"); }

bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

// A run without a key: the tests set their own.
struct NoKey {
  ScopedEnv file{"COSIM_KEY_FILE", ""};
  ScopedEnv key{"COSIM_KEY", ""};
};

std::string record(const std::string& tag, const std::vector<std::string>& extra = {}) {
  const std::string h5 = harness::temp_path("_" + tag + ".h5");
  std::vector<std::string> args{"--set", kEnd, "--record", harness::temp_path("_" + tag + ".lcmlog")};
  args.insert(args.end(), extra.begin(), extra.end());
  EXPECT_EQ(run_cosim_master(kConfig, h5, args), 0) << log_of(h5);
  return h5;
}
std::string log_path(const std::string& tag) { return harness::temp_path("_" + tag + ".lcmlog"); }

}  // namespace

TEST(BusReplay, Mass1AgainstTheRecordedMass2IsBitIdentical) {
  NoKey no_key;
  const std::string logger_log = harness::temp_path("_lcm_logger.lcmlog");
  std::remove(logger_log.c_str());
  // lcm-logger on the same bus, as on any other host: every COSIM_ channel.
  harness::Process logger = harness::spawn(
      {"/usr/bin/lcm-logger", "--lcm-url=" + harness::bus_url() + "&recv_buf_size=4194304", "-c", "COSIM_.*", "-f", "-q", logger_log},
      logger_log + ".out");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const std::string a = record("recorded");
  const std::string log = log_path("recorded");
  kill(logger.pid, SIGINT);
  EXPECT_EQ(harness::wait_for(logger, 10), 0) << harness::read_text(logger_log + ".out");

  // LCM's reader (lcm::LogFile, as lcm-logplayer) reads the whole recording.
  const std::string session = text(a, "bus/recording/session");
  ASSERT_EQ(session.size(), 16u);
  const auto events = replay_harness::read_log(log);
  ASSERT_EQ(static_cast<double>(events.size()), number(a, "bus/recording/events"));
  std::map<std::string, int> per_channel;
  for (const auto& e : events) ++per_channel[e.channel];
  const std::string prefix = "COSIM_" + session + "_";
  // 500 steps; step 0 is done 3 times (startup_iterations 2): 502 requests, plus every resend,
  // each sent twice (redundancy, docs/protocol.md); a participant answers the first copy it
  // hears twice and the other once, so up to three replies per request sent.
  for (const std::string p : {"mass1", "mass2"}) {
    const int resends = static_cast<int>(number(a, "participants/" + p + "/bus/resends"));
    ASSERT_GE(resends, 0);
    EXPECT_EQ(per_channel[prefix + p + "_REQ"], 2 * (kSteps + 2 + resends)) << p;
    EXPECT_GE(per_channel[prefix + p + "_REP"], kSteps + 2) << p;
    EXPECT_LE(per_channel[prefix + p + "_REP"], 3 * (kSteps + 2 + resends)) << p;
  }
  EXPECT_GE(per_channel[prefix + "mass1_RDY"], 1);
  EXPECT_GE(per_channel[prefix + "END"], 1);  // the terminate, caught after the last step
  EXPECT_EQ(events.front().channel, prefix + "LOG");
  EXPECT_EQ(events.back().channel, prefix + "LOG");
  for (const auto& e : events) EXPECT_EQ(e.channel.rfind(prefix, 0), 0u) << e.channel;

  // mass1 live, mass2 from the log: every dataset bit for bit, mass2 never started.
  const std::string b = harness::temp_path("_replay_mass1.h5");
  ASSERT_EQ(run_cosim_master(kConfig, b, {"--set", kEnd, "--replay", log, "--replay-side", "mass1"}), 0) << log_of(b);
  expect_bit_identical(a, b);
  const std::string blog = log_of(b);
  EXPECT_TRUE(contains(blog, "replaying mass2 from " + log + " (session " + session)) << blog;
  EXPECT_TRUE(contains(blog, "mass1: joined session")) << blog;
  EXPECT_FALSE(contains(blog, "mass2: joined session")) << blog;
  EXPECT_TRUE(contains(blog, "It did not diverge: all 502 request(s) to mass2 were bit-identical")) << blog;
  EXPECT_EQ(text(b, "status"), "finished");
  EXPECT_EQ(text(b, "replay/log"), log);
  EXPECT_EQ(text(b, "replay/session"), session);
  EXPECT_EQ(text(b, "replay/played"), "mass2");
  EXPECT_EQ(text(b, "replay/live"), "mass1");
  EXPECT_EQ(number(b, "replay/diverged"), 0);
  EXPECT_EQ(number(b, "replay/diverged_at_step"), -1);
  EXPECT_EQ(number(b, "replay/outputs_differ_at_step"), -1);
  EXPECT_EQ(number(b, "replay/requests_compared"), kSteps + 2);
  EXPECT_EQ(number(b, "replay/outputs_compared"), kSteps + 2);
  EXPECT_EQ(number(b, "replay/complete_log"), 1);

  // The other way round: mass2 live against the recorded mass1.
  const std::string c = harness::temp_path("_replay_mass2.h5");
  ASSERT_EQ(run_cosim_master(kConfig, c, {"--set", kEnd, "--replay", log, "--replay-side", "mass2"}), 0) << log_of(c);
  expect_bit_identical(a, c);
  EXPECT_FALSE(contains(log_of(c), "mass1: joined session"));
  EXPECT_EQ(text(c, "replay/played"), "mass1");

  // lcm-logger's log of the same run (no records of the master's; announces and every channel
  // of the session) replays the same, named by its session. lcm-logger 1.3.1 drops messages
  // when it is not scheduled for a while (its subscription queue holds 30; measured on this
  // loaded host: 0 to 460 of 2025 lost): the replay then names the first step it has no reply
  // for and how far the log can be replayed, and that part replays bit for bit.
  const std::string d = harness::temp_path("_replay_logger.h5");
  auto replay_logger_log = [&](const std::string& end) {
    return run_cosim_master(kConfig, d, {"--set", end, "--replay", logger_log, "--replay-side", "mass1",
                                         "--replay-session", session});
  };
  int rows = kSteps + 1;
  int code = replay_logger_log(kEnd);
  if (code == 2) {
    const std::string msg = log_of(d);
    const std::string at_most = "Set time.end to at most ";
    ASSERT_TRUE(contains(msg, "holds no reply of 'mass2' to step ")) << msg;
    ASSERT_TRUE(contains(msg, "the log ends there or lost the message (recorded with lcm-logger?)")) << msg;
    ASSERT_TRUE(contains(msg, at_most)) << msg;
    const double end = std::stod(msg.substr(msg.find(at_most) + at_most.size()));
    std::printf("lcm-logger lost messages; its log replays to t = %g s\n", end);
    rows = static_cast<int>(std::lround(end / 5e-4)) + 1;
    if (rows < 2) GTEST_SKIP() << "lcm-logger lost the first reply: nothing to replay";
    code = replay_logger_log("time.end=" + std::to_string(end));
  }
  ASSERT_EQ(code, 0) << log_of(d);
  for (const auto& ds : kDatasets) {
    const auto x = harness::read_dataset(a, ds), y = harness::read_dataset(d, ds);
    const std::size_t width = x.size() / (kSteps + 1);
    ASSERT_EQ(y.size(), width * rows) << ds;
    EXPECT_EQ(std::memcmp(x.data(), y.data(), y.size() * sizeof(double)), 0) << ds;
  }
  EXPECT_EQ(number(d, "replay/complete_log"), 0);
  EXPECT_EQ(number(d, "replay/diverged"), 0);
}

TEST(BusReplay, AChangedMass1ParameterGoesOnAndReportsWhereItDiverged) {
  NoKey no_key;
  // Without start-up iterations a step is one request: the divergence step is plain.
  const std::string a = record("recorded", {"--set", "startup_iterations=0"});
  const std::string changed = "participants.mass1.parameters.damping=0.5";  // recorded: 0.2
  // Where a live run with the change first sends mass2 other inputs than the recorded run.
  const std::string live = harness::temp_path("_live_changed.h5");
  ASSERT_EQ(run_cosim_master(kConfig, live, {"--set", kEnd, "--set", "startup_iterations=0", "--set", changed}), 0)
      << log_of(live);
  int64_t expected = -1;
  for (const char* ds : {"connections/mass2.x/sent", "connections/mass2.v/sent"}) {
    const auto x = harness::read_dataset(a, ds), y = harness::read_dataset(live, ds);
    ASSERT_EQ(x.size(), y.size());
    const std::size_t width = x.size() / (kSteps + 1);
    for (std::size_t row = 1; row <= kSteps; ++row)  // row 0: before the first step
      if (std::memcmp(&x[row * width], &y[row * width], width * sizeof(double)) != 0) {
        const int64_t step = static_cast<int64_t>(row) - 1;
        expected = expected < 0 ? step : std::min(expected, step);
        break;
      }
  }
  ASSERT_GE(expected, 0) << "the change must reach mass2's inputs";

  const std::string r = harness::temp_path("_replay_changed.h5");
  ASSERT_EQ(run_cosim_master(kConfig, r,
                   {"--set", kEnd, "--set", "startup_iterations=0", "--set", changed, "--replay", log_path("recorded"),
                    "--replay-side", "mass1"}),
            0)
      << log_of(r);
  const std::string rlog = log_of(r);
  // The run goes on to the end, and says where it left the recording.
  EXPECT_EQ(text(r, "status"), "finished");
  EXPECT_EQ(harness::read_dataset(r, "time").size(), static_cast<std::size_t>(kSteps + 1));
  EXPECT_EQ(number(r, "replay/diverged"), 1);
  EXPECT_EQ(number(r, "replay/diverged_at_step"), expected);
  EXPECT_TRUE(contains(rlog, "diverged from the recording at step " + std::to_string(expected) + " ")) << rlog;
  EXPECT_TRUE(contains(text(r, "replay/diverged_detail"), "input 'x'") ||
              contains(text(r, "replay/diverged_detail"), "input 'v'"))
      << text(r, "replay/diverged_detail");
  // mass1's own outputs change at once (damping acts in the first step).
  EXPECT_EQ(number(r, "replay/outputs_differ_at_step"), 0);
  // mass2 is played whatever it is asked: its forces are the recorded ones, bit for bit.
  EXPECT_TRUE(bit_identical(harness::read_dataset(a, "participants/mass2/outputs/force"),
                            harness::read_dataset(r, "participants/mass2/outputs/force")));
  // Until the divergence mass1 got the recorded forces, as in the live run with the change.
  const auto x_rec = harness::read_dataset(a, "participants/mass1/outputs/x");
  const auto x_live = harness::read_dataset(live, "participants/mass1/outputs/x");
  const auto x_rep = harness::read_dataset(r, "participants/mass1/outputs/x");
  for (int64_t row = 0; row <= expected + 1; ++row) EXPECT_EQ(x_rep[row], x_live[row]) << row;
  EXPECT_NE(x_rep[kSteps], x_rec[kSteps]);
}

TEST(BusReplay, LogsOfAnotherSessionTruncatedChangedOrWithoutTheParticipantAreRefused) {
  NoKey no_key;
  const std::string a = record("a"), b = record("b");
  const std::string session_a = text(a, "bus/recording/session"), session_b = text(b, "bus/recording/session");
  ASSERT_NE(session_a, session_b);
  auto refused = [&](const std::string& tag, const std::string& log, std::vector<std::string> extra = {}) {
    const std::string h5 = harness::temp_path("_" + tag + ".h5");
    std::vector<std::string> args{"--set", kEnd, "--replay", log, "--replay-side", "mass1"};
    args.insert(args.end(), extra.begin(), extra.end());
    EXPECT_EQ(run_cosim_master(kConfig, h5, args), 2) << tag;
    std::ifstream probe(h5);
    EXPECT_FALSE(probe.good()) << tag << ": nothing is recorded when the log is refused";
    return log_of(h5);
  };

  // The log of run b when run a is asked for.
  std::string msg = refused("other_session", log_path("b"), {"--replay-session", session_a});
  EXPECT_TRUE(contains(msg, "replay refused: the log '" + log_path("b") + "' holds no message of session " + session_a +
                                " (--replay-session): it is the recording of another run. It holds session(s) " +
                                session_b + " (mass1, mass2)"))
      << msg;

  // Cut inside an event.
  const auto events = replay_harness::read_log(log_path("a"));
  ASSERT_GT(events.size(), 1000u);
  {
    std::ifstream in(log_path("a"), std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(harness::temp_path("_cut.lcmlog"), std::ios::binary).write(bytes.data(), bytes.size() / 2 + 7);
  }
  msg = refused("cut", harness::temp_path("_cut.lcmlog"));
  EXPECT_TRUE(contains(msg, "replay refused: the log '" + harness::temp_path("_cut.lcmlog") + "' is truncated: event ")) << msg;
  EXPECT_TRUE(contains(msg, "the recording was cut off or the file copied incompletely")) << msg;

  // Cut at an event boundary, halfway (the end record is gone with the second half).
  std::vector<replay_harness::Event> half(events.begin(), events.begin() + events.size() / 2);
  replay_harness::write_log(harness::temp_path("_half.lcmlog"), half);
  msg = refused("half", harness::temp_path("_half.lcmlog"));
  EXPECT_TRUE(contains(msg, "holds no reply of 'mass2' to step ")) << msg;
  EXPECT_TRUE(contains(msg, "the log has no end record: the recording was cut off")) << msg;
  EXPECT_TRUE(contains(msg, "Set time.end to at most ")) << msg;

  // One byte of a reply of mass2 changed.
  auto changed = events;
  int flipped = 0;
  for (auto& e : changed)
    if (replay_harness::ends_with(e.channel, "_mass2_REP") && ++flipped == 100) e.data[e.data.size() / 2] ^= 0x10;
  replay_harness::write_log(harness::temp_path("_changed.lcmlog"), changed);
  msg = refused("changed", harness::temp_path("_changed.lcmlog"));
  EXPECT_TRUE(contains(msg, "is corrupt: its end record counts ")) << msg;
  EXPECT_TRUE(contains(msg, "it was changed after recording")) << msg;

  // A log without mass2 (only mass1's channels, as lcm-logger -c 'COSIM_.*_mass1_.*' takes).
  std::vector<replay_harness::Event> only_mass1;
  for (const auto& e : events)
    if (contains(e.channel, "_mass1_")) only_mass1.push_back(e);
  replay_harness::write_log(harness::temp_path("_only_mass1.lcmlog"), only_mass1);
  msg = refused("only_mass1", harness::temp_path("_only_mass1.lcmlog"));
  EXPECT_TRUE(contains(msg, "holds no recorded run with participant(s) mass2 to play: it holds session(s) " +
                                session_a + " (mass1)"))
      << msg;

  // Not a log at all.
  msg = refused("not_a_log", harness::source(kConfig));
  EXPECT_TRUE(contains(msg, "is not an LCM event log: it does not start with LCM's sync word 0xEDA1DA01")) << msg;

  // The command line: a replay names its live side, which must be a participant, and leaves one
  // to play; a recording may not overwrite the log it replays.
  msg = refused("no_side", log_path("a"), {"--replay-side"});  // (the option without a value)
  EXPECT_TRUE(contains(msg, "--replay-side needs a value")) << msg;
  msg = refused("unknown_side", log_path("a"), {"--replay-side", "mass3"});
  EXPECT_TRUE(contains(msg, "--replay-side 'mass3': the config has no participant of that name (it has mass1, mass2)"))
      << msg;
  msg = refused("all_live", log_path("a"), {"--replay-side", "mass2"});
  EXPECT_TRUE(contains(msg, "--replay-side names every participant of the config (mass1, mass2): nothing is left to play"))
      << msg;
  msg = refused("record_onto_log", log_path("a"), {"--record", log_path("a")});
  EXPECT_TRUE(contains(msg, "--record")) << msg;
  EXPECT_TRUE(contains(msg, "--replay")) << msg;
  {
    const std::string h5 = harness::temp_path("_without_side.h5");
    EXPECT_EQ(run_cosim_master(kConfig, h5, {"--replay", log_path("a")}), 2);
    EXPECT_TRUE(contains(log_of(h5), "--replay needs --replay-side NAME")) << log_of(h5);
  }
  EXPECT_EQ(replay_harness::read_log(log_path("a")).size(), events.size()) << "the log must be untouched";

  // A played side with other parameters than recorded.
  msg = refused("played_changed", log_path("a"), {"--set", "participants.mass2.parameters.damping=0.5"});
  EXPECT_TRUE(contains(msg, "participants.mass2.parameters differ from the recorded ones")) << msg;
}

TEST(BusReplay, AKeyedRunsLogNeedsItsKey) {
  ScopedEnv file("COSIM_KEY_FILE", "");
  ScopedEnv key("COSIM_KEY", cosim::auth::new_key_hex());
  const std::string a = record("keyed");
  const std::string log = log_path("keyed");
  // The log holds the sealed envelopes as they were on the wire: payloads readable, tags only
  // checkable with the key.
  const auto events = replay_harness::read_log(log);
  int sealed = 0;
  for (const auto& e : events) sealed += cosim::auth::looks_sealed(e.data.data(), e.data.size()) ? 1 : 0;
  EXPECT_EQ(sealed, static_cast<int>(events.size()));

  const std::string b = harness::temp_path("_keyed_replay.h5");
  ASSERT_EQ(run_cosim_master(kConfig, b, {"--set", kEnd, "--replay", log, "--replay-side", "mass1"}), 0) << log_of(b);
  expect_bit_identical(a, b);
  EXPECT_EQ(number(b, "replay/keyed"), 1);
  EXPECT_TRUE(contains(log_of(b), "sealed: each checked with the key")) << log_of(b);

  key.set("");
  const std::string c = harness::temp_path("_keyed_no_key.h5");
  EXPECT_EQ(run_cosim_master(kConfig, c, {"--set", kEnd, "--replay", log, "--replay-side", "mass1"}), 2);
  EXPECT_TRUE(contains(log_of(c), "is the recording of a run with a key: its messages are sealed")) << log_of(c);
  EXPECT_TRUE(contains(log_of(c), "Give this master the run's key ($COSIM_KEY_FILE or $COSIM_KEY)")) << log_of(c);

  key.set(cosim::auth::new_key_hex());
  const std::string d = harness::temp_path("_keyed_other_key.h5");
  EXPECT_EQ(run_cosim_master(kConfig, d, {"--set", kEnd, "--replay", log, "--replay-side", "mass1"}), 2);
  EXPECT_TRUE(contains(log_of(d), "does not match this master's key")) << log_of(d);
}
