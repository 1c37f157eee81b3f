// The participant side of the protocol. A machine or soil model implements Model (a thin
// adapter over the model, which itself knows nothing of the bus); ParticipantCore holds the
// protocol logic (configure, step identity, cached replies, validation) independent of the
// transport; run_participant serves a Model on the LCM bus.
#pragma once

#include <cosim/configure_t.hpp>
#include <cosim/ready_t.hpp>
#include <cosim/step_reply_t.hpp>
#include <cosim/step_request_t.hpp>

#include <yaml-cpp/yaml.h>

#include <atomic>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cosim/polynomial.hpp"
#include "cosim/signal.hpp"
#include "cosim/time.hpp"

namespace cosim {

struct RunInfo {
  std::string participant;
  TimePoint t_start{};
  TimePoint t_end{};
  Duration macro_step{};
  // A resumed run (cosim_master --resume): load_checkpoint follows configure and the first step
  // starts at resume_time (t_start + resume_steps_done macro steps, or an adaptive step's recorded end). 0 for a fresh start.
  int64_t resume_steps_done = 0;
  TimePoint resume_time{};
};

// What a model sees of one macro step.
class StepInputs {
 public:
  StepInputs(TimePoint t_start, TimePoint t_end, const Polynomials& inputs)
      : t_start_(t_start), t_end_(t_end), inputs_(inputs) {}
  TimePoint t_start() const { return t_start_; }
  TimePoint t_end() const { return t_end_; }
  Duration length() const { return t_end_ - t_start_; }
  // The input `name` at time t (t_start <= t <= t_end), from its polynomial.
  Value at(const std::string& name, TimePoint t) const;
  const InputPolynomial& polynomial(const std::string& name) const;

 private:
  TimePoint t_start_, t_end_;
  const Polynomials& inputs_;
};

struct StepResult {
  Signals outputs;                  // at t_end
  std::optional<Signals> average;   // over the step, when asked
  std::vector<std::pair<std::string, double>> diagnostics;
  // The model ended itself (an FMU that reports fmi2Terminated) at this time, t_start..t_end of
  // the step: `outputs` are at that time and no further step follows; `ended_reason` says why.
  std::optional<TimePoint> ended_at;
  std::string ended_reason;
};

// Raised by a model for an input it cannot accept (the step is refused, the state kept).
struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class Model {
 public:
  virtual ~Model() = default;
  // Reads and validates the participant's parameters; raises config::ConfigError.
  virtual void configure(const YAML::Node& parameters, const RunInfo& run) = 0;
  virtual Ports inputs() const = 0;
  virtual Ports outputs() const = 0;
  virtual Duration inner_step() const = 0;
  virtual Signals initial_outputs() = 0;
  // Advances the model over [in.t_start(), in.t_end()].
  virtual StepResult step(const StepInputs& in, bool want_average) = 0;
  // Models that can go back to the start of the current step support iterations and rollback.
  virtual bool can_repeat() const { return false; }
  // Why not, for people, when can_repeat() is false ("" when there is nothing to say). Sent in
  // ready_t.error (which carries a refusal's reason when ok is false).
  virtual std::string repeat_note() const { return ""; }
  virtual void save_snapshot() {}
  virtual void restore_snapshot() {}
  // Checkpoints (docs/protocol.md#checkpoints-and-resume): a model that can write everything
  // its future steps depend on to one file, between steps, and read it back after configure()
  // so that the steps that follow are bit-identical to an uninterrupted run. Both raise
  // std::exception with a message naming the file and the problem.
  virtual bool can_checkpoint() const { return false; }
  virtual void save_checkpoint(const std::string& path) {}
  virtual void load_checkpoint(const std::string& path) {}
};

class ParticipantCore {
 public:
  ParticipantCore(std::string name, Model& model);

  const std::string& name() const { return name_; }
  bool bound() const { return session_ != 0; }
  int64_t session() const { return session_; }
  int64_t busy_step() const { return busy_step_.load(); }   // -1 when idle
  int32_t busy_iteration() const { return busy_iteration_.load(); }
  // The last completed step and its iteration; safe to read from another thread (heartbeats).
  int64_t last_step() const { return done_step_.load(); }
  int32_t last_iteration() const { return done_iteration_.load(); }
  TimePoint time() const { return t_now_; }
  uint64_t ignored_messages() const { return ignored_; }

  // Who this process is (announce_t, ready_t, replies); the instance id 0 takes any configure.
  void set_identity(int64_t instance, std::string host, int32_t pid);
  // Started for one session (--session): a configure of any other session is refused.
  void reserve_for(int64_t session) { reserved_ = session; }
  int64_t instance() const { return instance_; }
  int64_t reserved_session() const { return reserved_; }
  const std::string& host() const { return host_; }
  int32_t pid() const { return pid_; }

  // Binds to the session on success. A repeated configure of the bound session gets the same
  // answer; a configure of another session while bound, or of a session other than the one
  // reserved, is refused (ok = false, bound_session_id set while bound). A configure for
  // another participant or instance is not for us (nullopt).
  std::optional<ready_t> configure(const configure_t& message);
  // nullopt for messages that are not for us (other session or participant) or stale.
  std::optional<step_reply_t> handle(const step_request_t& request);
  // The session is over. finished: the run completed, so its checkpoints are of no further use
  // and the ones this process wrote or restored are deleted (and their folder, if empty).
  void end_session(bool finished);
  // The file of the checkpoint after `steps_done` steps of run `run_id`:
  // <folder>/<participant>_<run id, 16 hex digits>_<steps_done>.ckpt
  static std::string checkpoint_path(const std::string& folder, const std::string& participant,
                                     int64_t run_id, int64_t steps_done);

 private:
  step_reply_t run_step(const step_request_t& request);
  // Restores the checkpoint a resuming configure names; raises ProtocolError naming the file.
  void restore_checkpoint(const configure_t& m);
  // Writes the checkpoint after the step just done (a temporary file renamed into place) and
  // deletes this process's checkpoints older than the previous one; raises on failure.
  void write_checkpoint();
  step_reply_t refuse(const step_request_t& request, int8_t status, const std::string& message);

  ready_t refusal(const configure_t& m, const std::string& error) const;

  std::string name_;
  Model& model_;
  int64_t instance_ = 0, reserved_ = 0;
  std::string host_;
  int32_t pid_ = 0;
  int64_t session_ = 0;
  RunInfo run_;
  Ports inputs_, outputs_;
  std::optional<ready_t> ready_;
  int64_t last_step_ = -1;     // last completed step index
  int32_t last_iteration_ = -1;
  TimePoint t_now_{};          // end of the last completed step
  TimePoint t_before_last_{};  // its start, for repeats
  std::optional<step_reply_t> cached_;
  std::atomic<int64_t> busy_step_{-1};
  std::atomic<int32_t> busy_iteration_{-1};
  std::atomic<int64_t> done_step_{-1};      // copies of last_step_, last_iteration_ for
  std::atomic<int32_t> done_iteration_{-1};  // the heartbeat thread
  uint64_t ignored_ = 0;
  std::string checkpoint_folder_;  // "" : no checkpoints asked
  int64_t run_id_ = 0;
  std::vector<std::string> checkpoints_;  // written or restored by this process, oldest first
  // The checkpoint this session resumed from: kept until the session finishes, so that the
  // record of the run, put back as it was when the resumed run cannot write it, can be resumed
  // again (docs/output.md#when-a-record-cannot-be-written).
  std::string resumed_from_;
};

// Serves `model` on the bus until the master terminates the session. Command line:
//   NAME [--name NAME] [--bus URL] [--session HEX] [--idle-timeout SECONDS] [--wait SECONDS]
// Returns the process exit code.
int run_participant(Model& model, const std::string& default_name, int argc, char** argv);

// The command line of a participant with a config file of its own:
//   PROGRAM [CONFIG.yaml] [--set dotted.key=value ...] [run_participant's options]
struct ParticipantArgs {
  std::string config_path;  // "" when none was given
  std::string config_dir;   // its folder, for relative input paths ("" without a file)
  YAML::Node config;        // the file (an empty map without one), --set applied
  std::vector<char*> rest;  // argv[0] and run_participant's options
};
// Raises config::ConfigError for a second config file, a --set without a value, a malformed
// override or an unreadable file; `require_config` makes a missing file an error too.
ParticipantArgs parse_participant_args(int argc, char** argv, bool require_config);

}  // namespace cosim
