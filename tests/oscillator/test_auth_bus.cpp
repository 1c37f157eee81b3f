// The oscillator on an authenticated bus (docs/security.md): with a key, an attacker on the
// same bus URL without it (a thread of this test with its own LCM endpoint) forges replies,
// step requests, busy heartbeats and a terminate and replays captured replies and requests;
// every one is dropped, counted (the master's in /bus/auth, the participants' in their exit
// lines) and logged, and the record is bit-identical to an undisturbed keyed run and to a run
// without a key. A participant without the key cannot join, and forged busy heartbeats do not
// keep a killed participant alive.
#include <cosim/announce_t.hpp>
#include <cosim/auth.hpp>
#include <cosim/bus.hpp>
#include <cosim/heartbeat_t.hpp>
#include <cosim/sealed_bus.hpp>
#include <cosim/terminate_t.hpp>
#include <signal.h>
#include <sys/stat.h>

#include <atomic>
#include <cstdlib>
#include <cstring>
#include <lcm/lcm-cpp.hpp>
#include <mutex>
#include <optional>
#include <regex>

#include "harness.hpp"
#include "replay_harness.hpp"

namespace {

bool bit_identical(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

const std::vector<std::string> kRecorded{"time",
                                         "participants/mass1/outputs/x",
                                         "participants/mass1/outputs/v",
                                         "participants/mass2/outputs/force",
                                         "connections/mass1.force/predicted",
                                         "connections/mass1.force/sent",
                                         "connections/mass2.x/sent",
                                         "connections/mass2.v/predicted"};

using replay_harness::ScopedEnv;

double number(const std::string& h5, const std::string& name) {
  const auto v = harness::read_dataset(h5, name);
  return v.size() == 1 ? v[0] : -1;
}

// The counts a participant prints at exit: "<name>: authenticated bus: N message(s) accepted;
// dropped a malformed, b forged, c of another session, d replayed".
struct Dropped {
  long malformed = -1, forged = -1, other_session = -1, replayed = -1;
};
Dropped dropped_by(const std::string& log, const std::string& who) {
  Dropped d;
  const std::regex re(who + ": authenticated bus: [0-9]+ message\\(s\\) accepted; dropped ([0-9]+) malformed, "
                            "([0-9]+) forged, ([0-9]+) of another session, ([0-9]+) replayed");
  std::smatch m;
  if (std::regex_search(log, m, re)) {
    d.malformed = std::stol(m[1]);
    d.forged = std::stol(m[2]);
    d.other_session = std::stol(m[3]);
    d.replayed = std::stol(m[4]);
  }
  return d;
}

template <class M>
std::vector<std::uint8_t> encode(const M& m) {
  std::vector<std::uint8_t> b(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

template <class M>
bool decode(const std::vector<std::uint8_t>& sealed, M& m) {
  const auto p = cosim::auth::unverified_payload(sealed.data(), sealed.size());
  return p && m.decode(p->first, 0, static_cast<int>(p->second)) == static_cast<int>(p->second);
}

// Listens to every channel of the bus without the key. It learns the session from the channel
// names and reads the (unencrypted) payloads of the sealed messages; once it has seen mass2
// answer step 20 it attacks: what it sends, per kind, is counted in `sent`.
class Attacker {
 public:
  enum Mode { full_attack, busy_heartbeats_for_mass2 };

  struct Sent {
    int forged_replies = 0, plain_replies = 0, forged_requests = 0, replayed_replies = 0,
        replayed_requests = 0, forged_heartbeats = 0, forged_terminates = 0, plain_terminates = 0;
  };

  Attacker(const std::string& url, Mode mode)
      : lcm_(url), mode_(mode), wrong_key_(cosim::auth::parse_key_hex(cosim::auth::new_key_hex(), "attacker")) {
    lcm_.subscribe(".*", &Attacker::on_message, this);
    thread_ = std::thread([this] {
      while (!stop_) {
        lcm_.handleTimeout(10);
        std::unique_lock<std::mutex> lock(mutex_);
        if (mode_ == full_attack && ready_to_attack() && !attacked_) {
          lock.unlock();
          attack();
        } else if (mode_ == busy_heartbeats_for_mass2 && reply_ && seconds_since_beat_.seconds() > 0.02) {
          const step_reply_snapshot r = *reply_;
          lock.unlock();
          forge_busy_heartbeat(r.decoded.step_index + 1);
          seconds_since_beat_.restart();
        }
      }
    });
  }
  ~Attacker() {
    stop_ = true;
    thread_.join();
  }
  bool good() const { return lcm_.good(); }
  bool attacked() const { return attacked_; }
  Sent sent() {
    std::lock_guard<std::mutex> lock(mutex_);
    return sent_;
  }

 private:
  struct step_reply_snapshot {
    std::vector<std::uint8_t> bytes;
    cosim::step_reply_t decoded;
  };

  bool ready_to_attack() const { return session_ != 0 && reply_ && request_ && reply_->decoded.step_index >= 20; }

  void on_message(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    static const std::regex re("COSIM_([0-9a-f]{16})_(.*)");
    std::smatch m;
    if (!std::regex_match(channel, m, re)) return;
    const std::vector<std::uint8_t> bytes(static_cast<const std::uint8_t*>(rbuf->data),
                                          static_cast<const std::uint8_t*>(rbuf->data) + rbuf->data_size);
    std::lock_guard<std::mutex> lock(mutex_);
    if (m[2] == "mass2_REP" && !attacked_) {
      cosim::step_reply_t r;
      if (decode(bytes, r) && r.participant == "mass2" && r.status == cosim::step_reply_t::OK) {
        session_ = std::stoull(m[1], nullptr, 16);
        reply_ = step_reply_snapshot{bytes, r};
      }
    } else if (m[2] == "mass1_REQ" && !attacked_) {
      cosim::step_request_t q;
      if (decode(bytes, q)) request_ = std::make_pair(bytes, q);
    }
  }

  void publish_sealed(const std::string& channel, const std::string& sender, const std::vector<std::uint8_t>& payload) {
    cosim::auth::Sealer sealer(wrong_key_, sender);
    const auto env = sealer.seal(channel, session_, payload.data(), payload.size());
    lcm_.publish(channel, env.data(), static_cast<unsigned>(env.size()));
  }
  void publish_plain(const std::string& channel, const std::vector<std::uint8_t>& payload) {
    lcm_.publish(channel, payload.data(), static_cast<unsigned>(payload.size()));
  }

  void forge_busy_heartbeat(int64_t step) {
    cosim::heartbeat_t h{};
    std::int64_t instance;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      h.session_id = session_;
      instance = reply_->decoded.instance_id;
    }
    h.sender = "mass2";
    h.instance_id = instance;
    h.host = "attacker";
    h.pid = 1;
    h.state = cosim::heartbeat_t::BUSY;
    h.step_index = step;
    publish_sealed(cosim::channel::heartbeat(session_), cosim::envelope_sender("mass2", instance), encode(h));
    std::lock_guard<std::mutex> lock(mutex_);
    ++sent_.forged_heartbeats;
  }

  void attack() {
    step_reply_snapshot reply;
    std::pair<std::vector<std::uint8_t>, cosim::step_request_t> request;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      reply = *reply_;
      request = *request_;
    }
    const std::string rep = cosim::channel::reply(session_, "mass2");
    const std::string req = cosim::channel::request(session_, "mass1");
    const std::string mass2 = cosim::envelope_sender("mass2", reply.decoded.instance_id);
    Sent s;
    // Forged replies to the next steps, with a doubled force: sealed with another key ...
    for (int j = 1; j <= 3; ++j) {
      cosim::step_reply_t r = reply.decoded;
      r.step_index += j;
      for (auto& v : r.outputs.scalars) v.value *= 2;
      publish_sealed(rep, mass2, encode(r));
      ++s.forged_replies;
    }
    // ... and one without an envelope, as a process without a key would send it.
    {
      cosim::step_reply_t r = reply.decoded;
      r.step_index += 4;
      publish_plain(rep, encode(r));
      ++s.plain_replies;
    }
    // Forged step requests to mass1: the next step, and a redo of the captured one.
    for (int j = 0; j < 2; ++j) {
      cosim::step_request_t q = request.second;
      if (j == 0) q.step_index += 1;
      else q.iteration += 1;
      for (auto& p : q.inputs.scalars)
        for (auto& c : p.coefficients) c += 0.5;
      publish_sealed(req, cosim::envelope_sender("master", session_), encode(q));
      ++s.forged_requests;
    }
    // Replays: the captured sealed bytes, unchanged.
    for (int j = 0; j < 2; ++j) {
      publish_plain(rep, reply.bytes);
      ++s.replayed_replies;
    }
    publish_plain(req, request.first);
    ++s.replayed_requests;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      sent_ = s;
    }
    // Busy heartbeats for mass2, working on the step after the captured one.
    for (int j = 0; j < 5; ++j) {
      forge_busy_heartbeat(reply.decoded.step_index + 1);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    // A terminate: sealed with another key, and plain.
    cosim::terminate_t t{};
    t.session_id = session_;
    t.error = true;
    t.reason = "forged terminate";
    publish_sealed(cosim::channel::terminate(session_), cosim::envelope_sender("master", session_), encode(t));
    publish_plain(cosim::channel::terminate(session_), encode(t));
    std::lock_guard<std::mutex> lock(mutex_);
    ++sent_.forged_terminates;
    ++sent_.plain_terminates;
    attacked_ = true;
  }

  lcm::LCM lcm_;
  Mode mode_;
  cosim::auth::Key wrong_key_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> attacked_{false};
  std::mutex mutex_;
  std::int64_t session_ = 0;
  std::optional<step_reply_snapshot> reply_;
  std::optional<std::pair<std::vector<std::uint8_t>, cosim::step_request_t>> request_;
  Sent sent_;
  cosim::Stopwatch seconds_since_beat_;
};

}  // namespace

// The full attack on a keyed run of 4000 steps (under 1 s here), starting at step 20.
TEST(AuthenticatedBus, ForgedAndReplayedMessagesAreDroppedCountedAndTheRecordIsUnchanged) {
  const std::vector<std::string> run{"time.end=2.0"};
  const std::string plain = harness::temp_path("_plain.h5"), keyed = harness::temp_path("_keyed.h5"),
                    attacked = harness::temp_path("_attacked.h5");
  ScopedEnv key_file("COSIM_KEY_FILE", "");
  ScopedEnv key("COSIM_KEY", "");
  ASSERT_EQ(harness::run_master({"time.end=2.0", "bus.authenticate=false"}, plain, 60), 0) << harness::read_text(plain + ".log");
  EXPECT_EQ(number(plain, "bus/auth/keyed"), 0);

  key.set(cosim::auth::new_key_hex());  // the master and the participants it launches
  ASSERT_EQ(harness::run_master(run, keyed, 60), 0) << harness::read_text(keyed + ".log");
  EXPECT_EQ(number(keyed, "bus/auth/keyed"), 1);
  EXPECT_GT(number(keyed, "bus/auth/accepted"), 8000);  // two replies a step, and more
  for (const char* verdict : {"malformed", "forged", "other_session", "replayed"})
    EXPECT_EQ(number(keyed, std::string("bus/auth/") + verdict), 0) << verdict;

  Attacker attacker(harness::bus_url(), Attacker::full_attack);
  ASSERT_TRUE(attacker.good());
  const int code = harness::run_master(run, attacked, 60);
  const std::string log = harness::read_text(attacked + ".log");
  ASSERT_EQ(code, 0) << log;
  ASSERT_TRUE(attacker.attacked()) << "the attacker never saw mass2 answer step 20\n" << log;
  const Attacker::Sent s = attacker.sent();
  std::printf("sent: %d forged replies, %d plain replies, %d forged requests, %d replayed replies, "
              "%d replayed requests, %d forged busy heartbeats, %d forged + %d plain terminates\n",
              s.forged_replies, s.plain_replies, s.forged_requests, s.replayed_replies, s.replayed_requests,
              s.forged_heartbeats, s.forged_terminates, s.plain_terminates);

  // The master: forged replies and heartbeats, the plain reply, the replayed replies.
  EXPECT_EQ(number(attacked, "bus/auth/forged"), s.forged_replies + s.forged_heartbeats) << log;
  EXPECT_EQ(number(attacked, "bus/auth/malformed"), s.plain_replies) << log;
  EXPECT_EQ(number(attacked, "bus/auth/replayed"), s.replayed_replies) << log;
  EXPECT_EQ(number(attacked, "bus/auth/other_session"), 0) << log;
  // mass1: forged requests, heartbeats and terminate; the plain terminate; the replayed request.
  const Dropped m1 = dropped_by(log, "mass1"), m2 = dropped_by(log, "mass2");
  EXPECT_EQ(m1.forged, s.forged_requests + s.forged_heartbeats + s.forged_terminates) << log;
  EXPECT_EQ(m1.malformed, s.plain_terminates) << log;
  EXPECT_EQ(m1.replayed, s.replayed_requests) << log;
  EXPECT_EQ(m1.other_session, 0) << log;
  // mass2: forged heartbeats and terminate, the plain terminate.
  EXPECT_EQ(m2.forged, s.forged_heartbeats + s.forged_terminates) << log;
  EXPECT_EQ(m2.malformed, s.plain_terminates) << log;
  EXPECT_EQ(m2.replayed, 0) << log;
  // In the master's summary too.
  EXPECT_NE(log.find("cosim_master: authenticated bus: "), std::string::npos) << log;

  // Each kind logged, naming its channel.
  const std::string p = "COSIM_[0-9a-f]{16}_";
  for (const std::string& line :
       {"cosim_master: dropped a forged message on " + p + "mass2_REP",
        "cosim_master: dropped an unsealed message on " + p + "mass2_REP",
        "cosim_master: dropped a replayed message on " + p + "mass2_REP from mass2/",
        "cosim_master: dropped a forged message on " + p + "HB",
        "mass1: dropped a forged message on " + p + "mass1_REQ",
        "mass1: dropped a replayed message on " + p + "mass1_REQ from master/",
        "mass1: dropped a forged message on " + p + "HB", "mass2: dropped a forged message on " + p + "HB",
        "mass1: dropped a forged message on " + p + "END", "mass2: dropped a forged message on " + p + "END",
        "mass1: dropped an unsealed message on " + p + "END"})
    EXPECT_TRUE(std::regex_search(log, std::regex(line))) << line << "\n" << log;

  // Nothing of it reached the run: the record equals the undisturbed keyed run and the run
  // without a key, bit for bit, and the forged terminate did not end it.
  EXPECT_EQ(harness::read_string(attacked, "status"), "finished");
  for (const auto& name : kRecorded) {
    const auto a = harness::read_dataset(attacked, name);
    ASSERT_EQ(a.size() % 4001, 0u) << name;  // 4000 steps and the initial row
    EXPECT_TRUE(bit_identical(a, harness::read_dataset(keyed, name))) << name;
    EXPECT_TRUE(bit_identical(a, harness::read_dataset(plain, name))) << name;
  }
  EXPECT_EQ(log.find("master ended the session"), std::string::npos) << log;
}

// Master with the key, participants started by hand without it (mass1) or with another key
// (mass2): nobody joins, no step is recorded, and the master says why, naming both.
TEST(AuthenticatedBus, ParticipantWithoutTheKeyCannotJoin) {
  const std::string url = harness::bus_url();
  const std::string h5 = harness::temp_path(".h5");
  std::remove(h5.c_str());
  ScopedEnv key_file("COSIM_KEY_FILE", "");
  ScopedEnv key("COSIM_KEY", "");
  auto m1 = harness::spawn({harness::bin("oscillator_adapter"), "--side", "mass1", "--bus", url, "--wait", "20"},
                           h5 + ".mass1.log");
  key.set(cosim::auth::new_key_hex());
  auto m2 = harness::spawn({harness::bin("oscillator_adapter"), "--side", "mass2", "--bus", url, "--wait", "20"},
                           h5 + ".mass2.log");
  key.set(cosim::auth::new_key_hex());
  auto master = harness::spawn({harness::bin("cosim_master"), harness::source("configs/oscillator.yaml"), "--output",
                                h5, "--set", "bus.url=" + url, "--set", "participants.mass1.launch=null",
                                "--set", "participants.mass2.launch=null", "--set", "connect_timeout=3",
                                "--set", "output.csv=", "--set", "output.progress=off", "--set", "time.end=0.05"},
                               h5 + ".log");
  const int code = harness::wait_for(master, 30);
  const pid_t p1 = m1.pid, p2 = m2.pid;
  kill(m1.pid, SIGTERM);
  kill(m2.pid, SIGTERM);
  harness::wait_for(m1, 5);
  harness::wait_for(m2, 5);
  const std::string log = harness::read_text(h5 + ".log");
  EXPECT_EQ(code, 1) << log;
  EXPECT_NE(log.find("participant(s) mass1, mass2 cannot join: within 3 s on bus " + url +
                     " this master heard only unauthenticated participants, which it ignores: "),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("'mass1' pid " + std::to_string(p1) + " on "), std::string::npos) << log;
  EXPECT_NE(log.find(" (no key)"), std::string::npos) << log;
  EXPECT_NE(log.find("'mass2' pid " + std::to_string(p2) + " on "), std::string::npos) << log;
  EXPECT_NE(log.find(" (sealed with another key)"), std::string::npos) << log;
  EXPECT_NE(log.find("give every participant the run's key (docs/security.md)"), std::string::npos) << log;
  EXPECT_NE(log.find("cosim_master: dropped an unsealed message on COSIM_ANNOUNCE"), std::string::npos) << log;
  EXPECT_NE(log.find("cosim_master: dropped a forged message on COSIM_ANNOUNCE"), std::string::npos) << log;
  EXPECT_TRUE(harness::read_dataset(h5, "time").empty()) << "a step was recorded";
}

// The hang of an unauthenticated bus: forged busy heartbeats for a killed participant kept the
// master waiting. With a key they are dropped and the participant is declared gone on time.
TEST(AuthenticatedBus, ForgedBusyHeartbeatsDoNotKeepAKilledParticipantAlive) {
  const std::string url = harness::bus_url();
  const std::string h5 = harness::temp_path(".h5");
  ScopedEnv key_file("COSIM_KEY_FILE", "");
  ScopedEnv key("COSIM_KEY", cosim::auth::new_key_hex());
  Attacker attacker(url, Attacker::busy_heartbeats_for_mass2);
  ASSERT_TRUE(attacker.good());
  auto m1 = harness::spawn({harness::bin("oscillator_adapter"), "--side", "mass1", "--bus", url, "--wait", "60"},
                           h5 + ".mass1.log");
  auto m2 = harness::spawn({harness::bin("oscillator_adapter"), "--side", "mass2", "--bus", url, "--wait", "60"},
                           h5 + ".mass2.log");
  auto master = harness::spawn(
      {harness::bin("cosim_master"), harness::source("configs/oscillator.yaml"), "--output", h5, "--set",
       "bus.url=" + url, "--set", "participants.mass1.launch=null", "--set", "participants.mass2.launch=null",
       "--set", "participants.mass2.timeout=0.3", "--set", "participants.mass2.retries=2", "--set",
       "time.end=200", "--set", "output.csv=", "--set", "output.progress=off"},
      h5 + ".log");
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  kill(m2.pid, SIGKILL);  // from now on only the attacker speaks for mass2, every 20 ms
  const int code = harness::wait_for(master, 30);
  harness::wait_for(m2, 5);
  harness::wait_for(m1, 10);
  const Attacker::Sent s = attacker.sent();
  const std::string log = harness::read_text(h5 + ".log");
  std::printf("forged busy heartbeats for mass2 sent: %d\n", s.forged_heartbeats);
  EXPECT_EQ(code, 1) << log;
  EXPECT_NE(log.find("participant 'mass2' stopped answering"), std::string::npos) << log;
  EXPECT_NE(log.find("cosim_master: dropped a forged message on COSIM_"), std::string::npos) << log;
  EXPECT_GT(s.forged_heartbeats, 10);
  EXPECT_GT(number(h5, "bus/auth/forged"), 10) << log;
  EXPECT_EQ(harness::read_string(h5, "status").rfind("stopped: participant 'mass2'", 0), 0u);
}

// cosim_master --new-key FILE: a key only its owner can read, never overwriting a file, and it
// works as $COSIM_KEY_FILE; a key file others can read is refused before anything starts.
TEST(AuthenticatedBus, NewKeyIsPrivateAndNeverOverwritten) {
  const std::string path = harness::temp_path(".key");
  std::remove(path.c_str());
  harness::Process p = harness::spawn({harness::bin("cosim_master"), "--new-key", path}, path + ".log");
  ASSERT_EQ(harness::wait_for(p, 10), 0) << harness::read_text(path + ".log");
  struct stat st {};
  ASSERT_EQ(stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  const std::string first = harness::read_text(path);
  EXPECT_NO_THROW(cosim::auth::read_key_file(path));
  p = harness::spawn({harness::bin("cosim_master"), "--new-key", path}, path + ".log");
  EXPECT_EQ(harness::wait_for(p, 10), 2);
  EXPECT_NE(harness::read_text(path + ".log").find("exists; a key file is never overwritten"), std::string::npos);
  EXPECT_EQ(harness::read_text(path), first);

  chmod(path.c_str(), 0644);
  ScopedEnv key_file("COSIM_KEY_FILE", path);
  const std::string h5 = harness::temp_path(".h5");
  EXPECT_EQ(harness::run_master({"time.end=0.01"}, h5, 30), 2);
  EXPECT_NE(harness::read_text(h5 + ".log").find("bus key refused: key file '" + path +
                                                 "' can be read by others (mode 644); restrict it: chmod 600"),
            std::string::npos)
      << harness::read_text(h5 + ".log");
  chmod(path.c_str(), 0600);
  EXPECT_EQ(harness::run_master({"time.end=0.01"}, h5, 30), 0) << harness::read_text(h5 + ".log");
  EXPECT_EQ(number(h5, "bus/auth/keyed"), 1);
}
