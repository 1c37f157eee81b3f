// cosim_master and its bus, end to end with the oscillator (docs/security.md, docs/protocol.md):
// * a default run (no key in the environment, every participant launched) is keyed with a fresh
//   key of its own; replies forged by this test on the bus (unsealed, and sealed with another
//   key) are dropped, counted, and the record equals an undisturbed default run's bit for bit,
//   while the same forgery on a run with bus.authenticate: false reaches its record;
// * --record of a default run keeps the run's key beside the log (mode 600), and --replay finds it;
// * a run with participants started by hand and no key is refused with how to join a keyed run;
// * a bus port that another program holds is reported as such, naming the URL (not as
//   participants that do not answer).
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cosim/auth.hpp>
#include <cosim/bus.hpp>
#include <cosim/sealed_bus.hpp>
#include <cosim/step_reply_t.hpp>
#include <cosim/step_request_t.hpp>
#include <lcm/lcm-cpp.hpp>
#include <mutex>
#include <optional>
#include <regex>
#include <thread>

#include "harness.hpp"
#include "record_compare.hpp"
#include "replay_harness.hpp"

namespace {

using replay_harness::ScopedEnv;
using replay_harness::number;

bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

// No key in the environment of the test's processes.
struct NoKey {
  ScopedEnv file{"COSIM_KEY_FILE", ""};
  ScopedEnv key{"COSIM_KEY", ""};
};

template <class M>
std::vector<std::uint8_t> encode(const M& m) {
  std::vector<std::uint8_t> b(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

// A message as heard: the payload of an envelope (not checked: the forger has no key), or the
// plain encoding.
template <class M>
bool decode_heard(const std::uint8_t* data, std::size_t size, M& m) {
  if (const auto p = cosim::auth::unverified_payload(data, size))
    return m.decode(p->first, 0, static_cast<int>(p->second)) == static_cast<int>(p->second);
  return m.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size);
}

// Listens to the bus without the run's key. From step 20 on it answers every step request to
// mass2 at once with a reply of its own (the force of the last real reply, doubled, plus 1 N),
// alternately unsealed and sealed with another key.
class Forger {
 public:
  explicit Forger(const std::string& url)
      : lcm_(url), wrong_key_(cosim::auth::parse_key_hex(cosim::auth::new_key_hex(), "forger")) {
    lcm_.subscribe(".*", &Forger::on_message, this);
    thread_ = std::thread([this] {
      while (!stop_) lcm_.handleTimeout(10);
    });
  }
  ~Forger() {
    stop_ = true;
    thread_.join();
  }
  bool good() const { return lcm_.good(); }
  int plain() const { return plain_; }
  int sealed() const { return sealed_; }

 private:
  void on_message(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    static const std::regex re("COSIM_([0-9a-f]{16})_(mass2_REP|mass2_REQ)");
    std::smatch m;
    if (!std::regex_match(channel, m, re)) return;
    const auto* data = static_cast<const std::uint8_t*>(rbuf->data);
    const int64_t session = static_cast<int64_t>(std::stoull(m[1], nullptr, 16));
    if (m[2] == "mass2_REP") {
      cosim::step_reply_t r;
      if (decode_heard(data, rbuf->data_size, r) && r.status == cosim::step_reply_t::OK && r.participant == "mass2")
        last_ = r;
      return;
    }
    cosim::step_request_t q;
    if (!last_ || !decode_heard(data, rbuf->data_size, q) || q.step_index < 20 || q.step_index == answered_) return;
    answered_ = q.step_index;
    cosim::step_reply_t r = *last_;
    r.step_index = q.step_index;
    r.iteration = q.iteration;
    r.attempt = q.attempt;
    r.t_start_ns = q.t_start_ns;
    r.t_end_ns = q.t_end_ns;
    for (auto& v : r.outputs.scalars) v.value = 2 * v.value + 1;
    const auto payload = encode(r);
    const std::string rep = cosim::channel::reply(session, "mass2");
    if ((plain_ + sealed_) % 2 == 0) {
      lcm_.publish(rep, payload.data(), static_cast<unsigned>(payload.size()));
      ++plain_;
    } else {
      cosim::auth::Sealer sealer(wrong_key_, cosim::envelope_sender("mass2", r.instance_id));
      const auto env = sealer.seal(rep, session, payload.data(), payload.size());
      lcm_.publish(rep, env.data(), static_cast<unsigned>(env.size()));
      ++sealed_;
    }
  }

  lcm::LCM lcm_;
  cosim::auth::Key wrong_key_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::optional<cosim::step_reply_t> last_;
  int64_t answered_ = -1;
  std::atomic<int> plain_{0}, sealed_{0};
};

const std::vector<std::string> kRun{"time.end=1.0"};  // 2000 steps

// cosim_master on the oscillator with ARGS, as a user runs it (no bus option).
int default_run(const std::vector<std::string>& args, const std::string& h5) {
  std::vector<std::string> a{harness::bin("cosim_master"), harness::source("configs/oscillator.yaml"), "--output", h5,
                             "--set", "bus.url=" + harness::bus_url(), "--set", "output.csv=",
                             "--set", "output.progress=off"};
  a.insert(a.end(), args.begin(), args.end());
  harness::Process p = harness::spawn(a, h5 + ".log");
  return harness::wait_for(p, 120);
}

}  // namespace

TEST(MasterBus, ADefaultRunIsKeyedAndAForgedReplyIsDropped) {
  NoKey no_key;
  const std::string quiet = harness::temp_path("_quiet.h5"), forged = harness::temp_path("_forged.h5");
  ASSERT_EQ(harness::run_master(kRun, quiet, 60), 0) << harness::read_text(quiet + ".log");
  EXPECT_EQ(number(quiet, "bus/auth/keyed"), 1);
  EXPECT_TRUE(contains(harness::read_text(quiet + ".log"), "sealed with a fresh key for this run"))
      << harness::read_text(quiet + ".log");
  for (const char* verdict : {"malformed", "forged", "other_session", "replayed"})
    EXPECT_EQ(number(quiet, std::string("bus/auth/") + verdict), 0) << verdict;

  int plain = 0, sealed = 0;
  {
    Forger forger(harness::bus_url());
    ASSERT_TRUE(forger.good());
    ASSERT_EQ(harness::run_master(kRun, forged, 60), 0) << harness::read_text(forged + ".log");
    plain = forger.plain();
    sealed = forger.sealed();
  }
  std::printf("forged replies: %d unsealed, %d sealed with another key\n", plain, sealed);
  ASSERT_GT(plain + sealed, 100) << "the forger answered too few requests to tell";
  // The master dropped the forged replies it heard: unsealed ones as malformed, the others as
  // forged (its record counts until its end, so the replies to the last steps may come too late
  // to be counted; and a datagram may be lost).
  const double malformed = number(forged, "bus/auth/malformed"), wrong_key = number(forged, "bus/auth/forged");
  EXPECT_GT(malformed, plain / 2) << harness::read_text(forged + ".log");
  EXPECT_LE(malformed, plain);
  EXPECT_GT(wrong_key, sealed / 2) << harness::read_text(forged + ".log");
  EXPECT_LE(wrong_key, sealed);
  EXPECT_EQ(harness::read_string(forged, "status"), "finished");
  const auto c = record_compare::compare(quiet, forged);
  EXPECT_TRUE(c.identical()) << c.text();
  EXPECT_GE(c.compared, 20);
  std::printf("%d datasets bit-identical, %d run metadata skipped\n", c.compared, c.skipped);
}

// The same forger against a run that chose an unauthenticated bus: its replies reach the
// record (so the test above would see them if the key did not stop them), and the record's
// config says bus.authenticate: false.
TEST(MasterBus, WithoutAKeyTheForgedRepliesReachTheRecord) {
  NoKey no_key;
  const std::string quiet = harness::temp_path("_quiet.h5"), forged = harness::temp_path("_forged.h5");
  std::vector<std::string> run = kRun;
  run.push_back("bus.authenticate=false");
  ASSERT_EQ(harness::run_master(run, quiet, 60), 0) << harness::read_text(quiet + ".log");
  EXPECT_EQ(number(quiet, "bus/auth/keyed"), 0);
  EXPECT_TRUE(contains(harness::read_string(quiet, "config_effective"), "authenticate: false"));
  EXPECT_TRUE(contains(harness::read_text(quiet + ".log"), "bus not authenticated (bus.authenticate: false)"));
  {
    Forger forger(harness::bus_url());
    ASSERT_TRUE(forger.good());
    harness::run_master(run, forged, 60);
  }
  const auto c = record_compare::compare(quiet, forged);
  ASSERT_TRUE(c.opened) << harness::read_text(forged + ".log");
  EXPECT_FALSE(c.identical()) << "no forged reply reached an unauthenticated run";
  std::printf("unauthenticated run with forged replies: %zu datasets differ\n", c.differ.size());
}

// --record with a fresh key: the log is sealed with it, so the key is kept beside the log
// (mode 600) and --replay takes it from there; the replay equals the run.
TEST(MasterBus, TheRecordedLogOfADefaultRunKeepsItsKeyForTheReplay) {
  NoKey no_key;
  const std::string a = harness::temp_path("_recorded.h5"), b = harness::temp_path("_replayed.h5");
  const std::string log = harness::temp_path(".lcmlog");
  std::remove((log + ".key").c_str());
  ASSERT_EQ(default_run({"--set", "time.end=0.2", "--record", log}, a), 0) << harness::read_text(a + ".log");
  struct stat st {};
  ASSERT_EQ(stat((log + ".key").c_str(), &st), 0) << harness::read_text(a + ".log");
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_NO_THROW(cosim::auth::read_key_file(log + ".key"));
  ASSERT_EQ(default_run({"--set", "time.end=0.2", "--replay", log, "--replay-side", "mass1"}, b), 0)
      << harness::read_text(b + ".log");
  EXPECT_TRUE(contains(harness::read_text(b + ".log"), "sealed: each checked with the key")) << harness::read_text(b + ".log");
  const auto c = record_compare::compare(a, b);
  for (const auto& n : c.differ) ADD_FAILURE() << "differs: " << n;
}

TEST(MasterBus, HandStartedParticipantsWithoutAKeyAreToldHowToJoinAKeyedRun) {
  NoKey no_key;
  const std::string h5 = harness::temp_path(".h5");
  EXPECT_EQ(harness::run_master({"participants.mass1.launch=null", "connect_timeout=30"}, h5, 20), 2);
  const std::string log = harness::read_text(h5 + ".log");
  for (const char* part : {"'mass1' is started by hand", "cosim_master --new-key", "COSIM_KEY_FILE=",
                           "bus.authenticate: false", "participants.<name>.launch"})
    EXPECT_TRUE(contains(log, part)) << part << "\n" << log;
  EXPECT_FALSE(contains(log, "mass2: joined")) << "nothing is started for a run that is refused\n" << log;

  // With a key in the environment they join as before (the master launches mass2, mass1 by hand).
  ScopedEnv key("COSIM_KEY", cosim::auth::new_key_hex());
  const std::string h5b = harness::temp_path("_keyed.h5");
  harness::Process mass1 = harness::spawn({harness::bin("oscillator_adapter"), "--side", "mass1", "--name",
                                           "mass1", "--bus", harness::bus_url(), "--wait", "30"},
                                          h5b + ".mass1.log");
  EXPECT_EQ(harness::run_master({"participants.mass1.launch=null", "time.end=0.05"}, h5b, 60), 0)
      << harness::read_text(h5b + ".log");
  harness::wait_for(mass1, 10);
  EXPECT_EQ(number(h5b, "bus/auth/keyed"), 1);
}

// Another program holds the bus's UDP port without sharing it: LCM can only print "bind:
// Address already in use" and hear nothing. The master says so at once, naming the URL,
// instead of waiting for participants that cannot answer.
TEST(MasterBus, ABusPortHeldByAnotherProgramIsReportedAsSuch) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_ANY);
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);  // any free port, not shared
  socklen_t len = sizeof addr;
  ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len), 0);
  const std::string url = "udpm://239.255.76.67:" + std::to_string(ntohs(addr.sin_port)) + "?ttl=0";
  const std::string h5 = harness::temp_path(".h5");
  const int code = harness::run_master({"bus.url=" + url, "connect_timeout=60"}, h5, 50);
  ::close(fd);
  const std::string log = harness::read_text(h5 + ".log");
  EXPECT_EQ(code, 1) << log;
  EXPECT_TRUE(contains(log, "cannot bind the bus '" + url + "'")) << log;
  EXPECT_TRUE(contains(log, "Address already in use")) << log;
  EXPECT_FALSE(contains(log, "no answer from participant")) << log;
  EXPECT_FALSE(contains(log, "joined session")) << "no participant is started on a bus it cannot use\n" << log;
}
