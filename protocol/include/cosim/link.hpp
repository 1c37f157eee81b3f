// The master side of the protocol: a Transport configures participants and exchanges step
// requests and replies with them. LcmTransport does it over the bus with per-participant
// timeouts and resends; InProcessTransport calls ParticipantCore objects directly (same
// encoding, same validation) for tests and analysis tools.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "cosim/auth.hpp"
#include "cosim/participant_core.hpp"
#include "cosim/signal_wire.hpp"
#include "cosim/time.hpp"

namespace cosim {

// A participant failed, refused a step or stopped answering. participant() names it.
class LinkError : public std::runtime_error {
 public:
  LinkError(std::string participant, const std::string& message)
      : std::runtime_error(message), participant_(std::move(participant)) {}
  const std::string& participant() const { return participant_; }

 private:
  std::string participant_;
};

// The run was interrupted (SIGINT, SIGTERM): raised by the master's liveness check while it
// waits; the message is "interrupted" (the recorder writes /status "stopped: interrupted").
class Interrupted : public LinkError {
 public:
  explicit Interrupted(int signal) : LinkError("", "interrupted"), signal_(signal) {}
  int signal() const { return signal_; }

 private:
  int signal_;
};

// A participant refused its configuration: the message names its parameter.
class ParticipantConfigError : public LinkError {
 public:
  using LinkError::LinkError;
};

// A reply without the interval average its request asked for: the participant cannot average
// its outputs (the master names the connection that asked).
class MissingAverageError : public LinkError {
 public:
  using LinkError::LinkError;
};

// Copies of every request and fresh reply (redundancy against loss): 2, or $COSIM_BUS_COPIES
// (1 or 2: 1 turns the redundancy off, for measuring what it costs and saves); raises
// std::invalid_argument naming the variable for any other value.
int bus_copies();

// Per participant (config: participants.<name>.timeout, .retries; docs/protocol.md).
// Resends are not timed by these: each participant has an adaptive resend timeout
// (ResendTimer) measured from its round trips.
struct LinkSettings {
  // Liveness: a participant silent this long (no heartbeat, no reply) is declared gone. The
  // default tolerates a participant paused for 10 s and more (a stopped process, a swapping
  // host); the price is that a participant started by hand whose host goes away silently is
  // detected 12 s late (a launched one that dies is detected at once, by its exit).
  double timeout_s = 12.0;
  // A participant that is heard from but has neither answered a request nor reported working
  // on it (busy heartbeat) for (retries + 1) x timeout_s is reported (its replies never arrive).
  int retries = 3;
  // Launched by the master with --session: configured on the session's channel. Otherwise
  // the master configures the one free instance that announces this name.
  bool launched = false;
  // Redundancy against loss (docs/protocol.md#loss-recovery-and-liveness): every request goes
  // out this many times back to back (the participant sends a fresh reply as many times, and
  // answers a further copy of a request it answered from its cache, once). 1: no redundancy.
  // The default is bus_copies(): 2, or $COSIM_BUS_COPIES for measurements.
  int copies = bus_copies();
};

// Messages a test asks the transport to lose, once each: (participant, step_index).
struct FaultPlan {
  std::set<std::pair<std::string, int64_t>> drop_request;
  std::set<std::pair<std::string, int64_t>> drop_reply;
};

struct ParticipantInfo {
  Ports inputs, outputs;
  Duration inner_step{};
  bool can_repeat = false;
  bool can_checkpoint = false;  // saves and restores checkpoints (docs/protocol.md)
  std::string repeat_note;  // why it cannot repeat a step, when it says (ready_t.error with ok)
  Signals initial_outputs;
};

struct ExchangeStats {
  uint64_t resends = 0;
  uint64_t redundant_copies = 0;  // request copies sent beyond the first (LinkSettings::copies)
  uint64_t dropped_by_plan = 0;
  uint64_t ignored_replies = 0;  // duplicates, other steps, other sessions
  // Per participant: resends, and the resend timeout base (s) and smoothed network round
  // trip (s) at the end.
  std::map<std::string, uint64_t> resends_to;
  std::map<std::string, double> resend_timeout_s, srtt_s;
  // Per participant: configure messages sent until it answered (repeated every 0.5 s: more
  // than one means a copy was lost, for example a fragment of a large one, or it was slow).
  std::map<std::string, uint64_t> configure_sends;
  // Authentication (docs/security.md): whether the bus is keyed, and what the master's end of
  // it accepted and dropped, by verdict.
  auth::BusCounts auth;
};

// A reply as the master uses it, validated against the participant's declaration.
struct StepAnswer {
  Signals outputs;
  std::optional<Signals> average;
  std::vector<std::pair<std::string, double>> diagnostics;
  double compute_seconds = 0;
  double round_trip_seconds = 0;
  bool checkpointed = false;  // the checkpoint the request asked for was written
  // The participant ended itself at this time (<= the request's end; step_reply_t::ENDED): the
  // outputs are at that time and it takes no further step. ended_reason says why.
  std::optional<TimePoint> ended_at;
  std::string ended_reason;
};

class Transport {
 public:
  virtual ~Transport() = default;
  virtual int64_t session() const = 0;
  // Configures every participant; raises ParticipantConfigError for a refusal and LinkError
  // for a participant that does not answer within timeout_s.
  virtual std::map<std::string, ParticipantInfo> connect(const std::vector<configure_t>& configs,
                                                         double timeout_s) = 0;
  // Sends the requests (all at once) and returns their validated answers, in order.
  virtual std::vector<StepAnswer> exchange(const std::vector<step_request_t>& requests) = 0;
  virtual void terminate(bool error, const std::string& reason) = 0;
  virtual std::string describe() const = 0;

  const ExchangeStats& stats() const { return stats_; }
  void set_fault_plan(FaultPlan plan) { faults_ = std::move(plan); }
  // Called while waiting; may raise LinkError (for example when a launched process died).
  void set_liveness_check(std::function<void()> check) { liveness_ = std::move(check); }

 protected:
  // Validates a reply for `request` against the declared outputs; raises LinkError.
  StepAnswer accept(const step_request_t& request, const step_reply_t& reply,
                    const ParticipantInfo& info, double round_trip) const;
  ParticipantInfo accept_ready(const ready_t& ready) const;

  ExchangeStats stats_;
  FaultPlan faults_;
  std::function<void()> liveness_;
};

// With a key every message is sealed and only authentic ones of this session are taken
// (docs/security.md); without one the bus is unauthenticated. `program` names this side in the
// messages the transport prints itself.
std::unique_ptr<Transport> make_lcm_transport(const std::string& url, int64_t session,
                                              std::map<std::string, LinkSettings> links,
                                              std::optional<auth::Key> key = std::nullopt,
                                              const std::string& program = "cosim_master");
// participants: name -> core; the cores must outlive the transport.
std::unique_ptr<Transport> make_in_process_transport(
    int64_t session, std::map<std::string, ParticipantCore*> participants);

}  // namespace cosim
