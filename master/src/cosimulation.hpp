// The co-simulation loop: handshake and wiring check, then macro steps in the configured
// scheme. Observers (recorder, CSV, progress) see every step; the loop writes no files.
#pragma once

#include <cosim/link.hpp>

#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "config.hpp"
#include "coupling_algorithm.hpp"
#include "cosim/stopwatch.hpp"
#include "predictor.hpp"

namespace master {

struct ConnectionRecord {
  cosim::InputPolynomial sent;  // the polynomial the consumer got (last iteration)
  cosim::Value predicted;       // use: end: sent evaluated at t_end; use: average: its mean over the step
  cosim::Value received;        // the source's output at t_end
  cosim::Value received_average;  // use: average: the source's mean over the step (else empty)
  // predicted - received (use: average: - received_average; orientation: rotation vector)
  std::vector<double> deviation;
  // What the consumer's side of a power pair compares: the received average for use: average,
  // else the end sample.
  const cosim::Value& received_for_power() const {
    return received_average.empty() ? received : received_average;
  }
};

// Where a connection is averaged, its interval means stand in for its end values (docs/output.md).
struct PowerRecord {
  double force_side = 0;   // F received * v predicted: what the force side computed against
  double motion_side = 0;  // F predicted * v received: what the motion side felt
  double residual = 0;     // force_side - motion_side
};

struct StepRecord {
  int64_t step_index = 0;
  TimePoint t_start{}, t_end{};
  int iterations = 1;
  // Implicit coupling: per coupling.convergence entry, |r| of the step's last iteration (else empty).
  std::vector<double> coupling_residuals;
  // Adaptive step (coupling.adaptive): the controller's error estimate of the step (<= 1: within
  // tolerance) and the attempts rejected before this one (reject_above); else NaN and 0.
  double step_error = std::numeric_limits<double>::quiet_NaN();
  int rejected = 0;
  std::map<std::string, cosim::Signals> outputs;
  std::map<std::string, std::vector<std::pair<std::string, double>>> diagnostics;
  std::vector<ConnectionRecord> connections;  // in config order
  std::vector<PowerRecord> power;             // in config order
  std::map<std::string, double> compute_seconds, round_trip_seconds;
  double master_seconds = 0;  // time in the master itself (predictors, observers excluded)
  double wall_seconds = 0;    // the whole step
  // Every participant wrote its checkpoint after this step (checkpoints.every): a stopped run
  // can be resumed from here once the recorder has recorded it.
  bool checkpoint = false;
  // With checkpoint: the coupling algorithm's state after this step (CouplingAlgorithm::save_state;
  // "" for one without state), which the record keeps for a resume.
  std::string algorithm_state;
};

// Where a resumed run continues (cosim_master --resume, master/src/resume.hpp reads it from
// the record): after steps_done steps, with the predictor history the record holds.
struct ResumePoint {
  int64_t steps_done = 0;
  // Per connection in config order: the source's values the predictors were given, rows
  // 0..steps_done of connections/<to>/received (row i at t_start + i macro steps), and for
  // use: average connections the means of connections/<to>/received_average (row i: the
  // step ending at row i's time; row 0 unused).
  std::vector<std::vector<cosim::Value>> received, received_average;
  // The times of rows 0..steps_done (/time): an adaptive step's are not multiples of
  // time.macro_step. Empty: t_start + i macro steps.
  std::vector<TimePoint> times;
  // /checkpoint/algorithm_state ("" when the record has none).
  std::string algorithm_state;
};

struct RunSetup {
  const Config* config = nullptr;
  std::map<std::string, cosim::ParticipantInfo> participants;
  int64_t session = 0;
  int64_t steps = 0;
  const cosim::ExchangeStats* bus = nullptr;  // the transport's counters, final at on_finish
  // Checkpoints: the run's id (the same across resumes) and the participants' folder.
  int64_t run_id = 0;
  std::string checkpoint_folder;
  // Steps recorded before this process started: 0, or the resume point's steps_done (the
  // observers continue the record after that many steps instead of starting it).
  int64_t first_step = 0;
  TimePoint first_time{};  // the time after them
};

class Observer {
 public:
  virtual ~Observer() = default;
  virtual void on_start(const RunSetup&) {}
  virtual void on_step(const StepRecord&) {}
  // ok = false: the run stopped early; message says why. Observers keep what they have.
  virtual void on_finish(bool ok, const std::string& message) {}
};

// The participants as a coupling algorithm sees them (Coupling), the predictors between them,
// and the records of every step for the observers. The algorithm (make_algorithm(config)
// unless one is given; set up here with the config) owns the step loop.
class CoSimulation final : private Coupling {
 public:
  CoSimulation(const Config& config, cosim::Transport& transport,
               std::unique_ptr<CouplingAlgorithm> algorithm = nullptr);
  void add_observer(Observer* observer) { observers_.push_back(observer); }
  // Checkpoints (config.checkpoints.every > 0, or a resume): the run's id and the folder the
  // participants write to (an absolute path on their hosts). Before connect().
  void set_checkpoints(int64_t run_id, std::string folder);
  // Continue a stopped run after resume.steps_done steps: the participants restore their
  // checkpoints in connect() and the predictors start from the recorded history. Before connect().
  void set_resume(ResumePoint resume);
  // The time after `steps` steps of this run (a resumed run's recorded times, else fixed steps).
  TimePoint time_after(int64_t steps) const;
  // Handshake and wiring check; raises ConfigError, ParticipantConfigError or LinkError.
  void connect();
  // All macro steps; raises LinkError on failure after telling the observers.
  void run();
  const RunSetup& setup() const { return setup_; }
  const CouplingAlgorithm& algorithm() const { return *algorithm_; }

 private:
  // The macro step between open_step and close_step.
  struct OpenStep {
    cosim::Stopwatch wall;
    double waiting = 0;  // s in exchanges
    StepRecord rec;
    std::vector<cosim::InputPolynomial> sent;       // per connection, the last one sent
    std::map<std::string, cosim::Signals> averages;  // participants asked for interval averages
    // Per connection, the value in place at the step's end once an exchange or the algorithm
    // has set one (else the prediction stands).
    std::vector<std::optional<cosim::Value>> end;
    // What the first pass over the step sent and got (kept when a second pass begins): the
    // explicit prediction's power residual, which the adaptive step controls.
    struct Pass {
      std::vector<cosim::InputPolynomial> sent;
      std::map<std::string, cosim::Signals> outputs, averages;
    };
    std::optional<Pass> first_pass;
  };

  // Coupling
  void open_step(int64_t step, TimePoint t0, TimePoint t1) override;
  void exchange(const std::vector<std::string>& group, int iteration, bool checkpoint) override;
  void close_step(int iterations, bool checkpoint) override;
  bool checkpoint_due(int64_t step, TimePoint t0, TimePoint t1) override;
  // Emits a closed step's record to the observers, with the algorithm's state at a checkpoint.
  void emit(StepRecord& rec);
  bool ended() const override { return ended_.has_value(); }
  void note_end(const std::string& name, const cosim::StepAnswer& answer, TimePoint t0, TimePoint t1);
  cosim::Value end_value(std::size_t connection) const override;
  void set_end_value(std::size_t connection, const cosim::Value& value) override;
  void set_residuals(std::vector<double> residuals) override;
  std::vector<std::pair<double, double>> last_power() const override { return last_power_; }
  void hold_step() override;
  void commit_step(double step_error, int rejected) override;
  void reject_step() override;

  std::vector<cosim::step_request_t> requests(const std::vector<std::string>& group, int64_t step,
                                       int iteration, TimePoint t0, TimePoint t1, bool checkpoint);
  // transport_.exchange, with a missing interval average named by its connection.
  std::vector<cosim::StepAnswer> exchange_requests(const std::vector<cosim::step_request_t>& requests);
  // The predictors' start: the initial outputs, or a resumed run's recorded history.
  void start_predictors();
  void record_connections(OpenStep& s) const;
  void record_power(StepRecord& rec, bool any_connection) const;

  // A participant ended itself (step_reply_t::ENDED): the run ends with this step; the message.
  std::optional<std::string> ended_;
  bool ended_inside_ = false;  // ... before the step's end: the step is not recorded
  const Config& config_;
  cosim::Transport& transport_;
  std::unique_ptr<CouplingAlgorithm> algorithm_;
  std::vector<Observer*> observers_;
  RunSetup setup_;
  std::vector<Predictor> predictors_;  // one per connection
  int max_order_ = 0;
  std::optional<OpenStep> open_;
  // The last closed step's bonds, from its first pass (the explicit prediction; the accepted
  // pass of an implicit step agrees with itself by construction).
  std::vector<std::pair<double, double>> last_power_;
  // Rejecting steps (hold_step): the held record, the predictors from before the step, and the
  // rejected attempts' times (added to the accepted attempt's record).
  bool hold_ = false;
  std::optional<StepRecord> held_;
  std::vector<Predictor> predictors_before_;
  struct Spent {
    double wall = 0, waiting = 0;
    std::map<std::string, double> compute, round_trip;
  } spent_;
  // The iterations of a step are numbered on across its attempts: a redo's iteration 0 goes out
  // as iteration_base_ (the participants then restore the step's start).
  int64_t last_opened_ = -1;
  int64_t due_step_ = -1;  // the last step checkpoint_due found due
  int iteration_base_ = 0, highest_iteration_ = -1;
  int64_t run_id_ = 0;
  std::string checkpoint_folder_;
  std::optional<ResumePoint> resume_;
};

}  // namespace master
