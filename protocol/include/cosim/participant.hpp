// The participant side of the protocol as a model sees it. A machine or soil model implements
// Model (a thin adapter over the model, which itself knows nothing of the bus); run_participant
// serves a Model on the LCM bus. No wire type is in reach from here: ParticipantCore, which
// holds the protocol logic on the messages, is in participant_core.hpp.
#pragma once

#include <yaml-cpp/yaml.h>

#include <functional>
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
  // Called instead of save_snapshot when the master says the step about to run will not be
  // redone (step_request_t.no_redo): the state at its start is accepted and need not be kept.
  // restore_snapshot is not called before the next save_snapshot.
  virtual void skip_snapshot() {}
  // Checkpoints (docs/protocol.md#checkpoints-and-resume): a model that can write everything
  // its future steps depend on to one file, between steps, and read it back after configure()
  // so that the steps that follow are bit-identical to an uninterrupted run. Both raise
  // std::exception with a message naming the file and the problem.
  virtual bool can_checkpoint() const { return false; }
  virtual void save_checkpoint(const std::string& path) {}
  virtual void load_checkpoint(const std::string& path) {}
};

// Serves `model` on the bus until the master terminates the session. Command line:
//   NAME [--name NAME] [--bus URL] [--session HEX] [--idle-timeout SECONDS] [--wait SECONDS]
// Returns the process exit code.
int run_participant(Model& model, const std::string& default_name, int argc, char** argv);

// The body of a participant program's main: an out-of-memory anywhere in it (std::bad_alloc)
// ends the process with "PROGRAM: out of memory ..." and exit code 1, and any other exception
// with "PROGRAM: error: ..." and 1, never std::terminate. Returns body's exit code otherwise.
int participant_main(const std::string& program, const std::function<int()>& body);
// The message of that out-of-memory exit, for programs that catch it themselves.
std::string out_of_memory_message(const std::string& program);

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
