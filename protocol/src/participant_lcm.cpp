// Serves a Model on the LCM bus. One thread handles LCM (as LCM requires); a second only
// publishes heartbeats so the master can tell a long step from a dead participant.
#include <cosim/announce_t.hpp>
#include <cosim/heartbeat_t.hpp>
#include <cosim/terminate_t.hpp>
#include <unistd.h>

#include <chrono>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <mutex>
#include <thread>
#include <tuple>

#include "cosim/bus.hpp"
#include "cosim/link.hpp"
#include "cosim/participant.hpp"
#include "cosim/number_arg.hpp"
#include "cosim/sealed_bus.hpp"
#include "cosim/stopwatch.hpp"

namespace cosim {
namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

using Clock = WallClock;

struct Server {
  lcm::LCM& lcm;
  SealedBus& bus;
  ParticipantCore& core;
  bool finished = false;
  bool error = false;
  Clock::time_point last_master = Clock::now();
  lcm::Subscription* req_sub = nullptr;
  std::optional<std::tuple<int64_t, int32_t, int32_t>> answered;  // the last request answered
  int copies = 2;                                                  // of a fresh reply (bus_copies)

  // A configure comes on this instance's channel before a session exists (sealed with session
  // 0), or on the channel of the session this process was started for.
  void on_configure(const lcm::ReceiveBuffer* rbuf, const std::string& ch) {
    configure_t msg;
    const int64_t sealed_for = ch == channel::configure(core.instance()) ? 0 : core.reserved_session();
    if (bus.open(rbuf, ch, {sealed_for}, msg) != SealedBus::Heard::ok) return;
    const configure_t* m = &msg;
    const bool was_bound = core.bound();
    auto ready = core.configure(*m);
    if (!ready) return;
    bus.publish(channel::ready(m->session_id, core.name()), m->session_id, *ready);
    if (!ready->ok) {
      std::cerr << core.name() << ": configuration from session " << id_hex(m->session_id)
                << " refused: " << ready->error << "\n";
      return;
    }
    last_master = Clock::now();
    if (!was_bound) {
      req_sub = lcm.subscribe(channel::request(core.session(), core.name()), &Server::on_request, this);
      lcm.subscribe(channel::heartbeat(core.session()), &Server::on_heartbeat, this);
      lcm.subscribe(channel::terminate(core.session()), &Server::on_terminate, this);
      std::cerr << core.name() << ": joined session " << id_hex(core.session()) << "\n";
    }
  }
  void on_request(const lcm::ReceiveBuffer* rbuf, const std::string& ch) {
    step_request_t msg;
    if (bus.open(rbuf, ch, {core.session()}, msg) != SealedBus::Heard::ok) return;
    const step_request_t* q = &msg;
    last_master = Clock::now();
    auto reply = core.handle(*q);
    if (!reply) return;
    // Redundancy (docs/protocol.md#loss-recovery-and-liveness): the master sends each request
    // twice; the first copy heard is answered twice (bus_copies), a further copy of the same
    // request (same step, iteration and attempt) once, from the cache.
    const auto id = std::make_tuple(q->step_index, q->iteration, q->attempt);
    const bool copy = answered && *answered == id;
    if (reply->status != step_reply_t::OK && !copy)
      std::cerr << core.name() << ": step " << q->step_index << ": " << reply->message << "\n";
    for (int i = 0; i < (copy ? 1 : copies); ++i)
      bus.publish(channel::reply(core.session(), core.name()), core.session(), *reply);
    answered = id;
  }
  void on_heartbeat(const lcm::ReceiveBuffer* rbuf, const std::string& ch) {
    heartbeat_t msg;
    if (bus.open(rbuf, ch, {core.session()}, msg) != SealedBus::Heard::ok) return;
    const heartbeat_t* h = &msg;
    if (h->session_id == core.session() && h->sender == "master") last_master = Clock::now();
  }
  void on_terminate(const lcm::ReceiveBuffer* rbuf, const std::string& ch) {
    terminate_t msg;
    if (bus.open(rbuf, ch, {core.session()}, msg) != SealedBus::Heard::ok) return;
    const terminate_t* t = &msg;
    if (t->session_id != core.session()) return;
    finished = true;
    error = t->error;
    core.end_session(!t->error);  // a finished run's checkpoints are deleted
    if (t->error) std::cerr << core.name() << ": master ended the session: " << t->reason << "\n";
  }
};

void usage(const std::string& name) {
  std::cerr << "usage: " << name
            << " [--name NAME] [--bus URL] [--session HEX] [--idle-timeout SECONDS] [--wait SECONDS]\n"
               "  --name          participant name the master's config uses (default "
            << name
            << ")\n"
               "  --bus           LCM URL (default: $LCM_DEFAULT_URL, else "
            << kDefaultBusUrl
            << ")\n"
               "  --session       join only this session (16 hex digits; the master passes it to the\n"
               "                  participants it launches); without it, any one master may take it\n"
               "  --idle-timeout  exit if the master is silent this long once joined (60)\n"
               "  --wait          exit if no master configures us within this time (0: never)\n";
}

}  // namespace

int run_participant(Model& model, const std::string& default_name, int argc, char** argv) {
  std::string name = default_name, url;
  double idle_timeout = 60.0, wait = 0.0;
  int64_t session = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* flag) -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(std::string(flag) + " needs a value");
      return argv[++i];
    };
    try {
      if (a == "--name") name = value("--name");
      else if (a == "--bus") url = value("--bus");
      else if (a == "--session") session = parse_id_hex(value("--session"));
      else if (a == "--idle-timeout")
        idle_timeout = parse_number_arg(a, value("--idle-timeout"), "seconds > 0 (e.g. 60)");
      else if (a == "--wait")
        wait = parse_number_arg(a, value("--wait"), "seconds >= 0 (0: wait forever)");
      else if (a == "--help" || a == "-h") { usage(default_name); return 0; }
      else throw std::invalid_argument("unknown argument '" + a + "'");
    } catch (const std::exception& e) {
      std::cerr << default_name << ": " << e.what() << "\n";
      usage(default_name);
      return 2;
    }
  }
  if (!(idle_timeout > 0) || !(wait >= 0)) {
    std::cerr << default_name << ": --idle-timeout must be > 0 and --wait >= 0\n";
    return 2;
  }
  if (!valid_name(name)) {
    std::cerr << default_name << ": --name '" << name
              << "' is not valid (1 to 32 characters of A-Z, a-z, 0-9, _)\n";
    return 2;
  }
  url = resolve_bus_url(url);
  lcm::LCM lcm(url);  // created first: LCM's select() cannot take fds >= 1024
  if (!lcm.good()) {
    std::cerr << name << ": cannot open the bus '" << url
              << "' (for multicast on loopback: ip route add 224.0.0.0/4 dev lo)\n";
    return 1;
  }
  // The shared key, from the environment only (docs/security.md): never on the command line.
  std::optional<auth::Key> key;
  try {
    key = auth::key_from_environment();
  } catch (const auth::AuthError& e) {
    std::cerr << name << ": " << e.what() << "\n";
    return 2;
  }
  int copies = 2;
  try {
    copies = bus_copies();
  } catch (const std::invalid_argument& e) {
    std::cerr << name << ": " << e.what() << "\n";
    return 2;
  }
  std::signal(SIGTERM, on_signal);
  std::signal(SIGINT, on_signal);

  char host[256] = {0};
  gethostname(host, sizeof host - 1);
  ParticipantCore core(name, model);
  core.set_identity(new_session_id(), host, static_cast<int32_t>(getpid()));
  core.reserve_for(session);
  SealedBus bus(lcm, key, envelope_sender(name, core.instance()), name);
  Server server{lcm, bus, core};
  server.copies = copies;
  // Configuration comes on channels of this process (its instance) or of its session only.
  lcm.subscribe(channel::configure(core.instance()), &Server::on_configure, &server);
  if (session != 0) lcm.subscribe(channel::configure(session, name), &Server::on_configure, &server);
  std::atomic<bool> running{true};
  std::thread beat([&] {
    // LCM's publish is thread-safe; this thread never calls handle().
    while (running) {
      if (core.bound()) {
        heartbeat_t h{};
        h.session_id = core.session();
        h.sender = core.name();
        h.instance_id = core.instance();
        h.host = core.host();
        h.pid = core.pid();
        const int64_t busy = core.busy_step();
        h.state = busy >= 0 ? heartbeat_t::BUSY : heartbeat_t::IDLE;
        h.step_index = busy >= 0 ? busy : core.last_step();
        h.iteration = busy >= 0 ? core.busy_iteration() : core.last_iteration();
        h.sim_time_ns = to_ns(core.time());
        bus.publish(channel::heartbeat(core.session()), core.session(), h);
      } else {
        announce_t a{};
        a.protocol_version = kProtocolVersion;
        a.participant = core.name();
        a.host = host;
        a.pid = core.pid();
        a.instance_id = core.instance();
        a.reserved_session_id = core.reserved_session();
        bus.publish(channel::announce(), 0, a);  // before a session: 0
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
  });

  const auto started = Clock::now();
  int code = 0;
  while (!server.finished && !g_stop) {
    const int r = lcm.handleTimeout(100);
    if (r < 0) {
      if (g_stop || errno == EINTR) continue;  // a signal: the loop condition decides
      std::cerr << name << ": the bus failed (lcm handle returned " << r << ": "
                << std::strerror(errno) << ")\n";
      code = 1;
      break;
    }
    const auto now = Clock::now();
    if (!core.bound() && wait > 0 &&
        seconds_between(started, now) > wait) {
      std::cerr << name << ": no master configured '" << name << "' within " << wait
                << " s on " << url << "\n";
      code = 3;
      break;
    }
    if (core.bound() &&
        seconds_between(server.last_master, now) > idle_timeout) {
      std::cerr << name << ": the master has been silent for " << idle_timeout
                << " s; leaving the session (raise --idle-timeout if that is expected)\n";
      code = 3;
      break;
    }
  }
  running = false;
  beat.join();
  // What was dropped, if anything (each kind was logged as it came, a few per channel).
  const AuthStats auth_stats = bus.stats();
  if (auth_stats.counts.rejected() > 0 || auth_stats.unreadable > 0) {
    const std::string line = name + ": " + auth_summary(auth_stats) + "\n";
    std::fputs(line.c_str(), stderr);  // one write: participants may share the master's log
  }
  if (g_stop && !server.finished) {
    std::cerr << name << ": stopped by a signal\n";
    return 0;
  }
  if (server.finished && server.error) code = 1;
  return code;
}

}  // namespace cosim
