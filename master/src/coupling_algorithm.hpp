// Coupling algorithms: what decides, step after step, which participants exchange what and how
// far time advances. CoSimulation (cosimulation.hpp) offers the participants through the
// Coupling interface below: open a macro step, let groups of participants step over it (once,
// or again from its start: an iteration), close it. An algorithm owns the step loop, the
// start-up iterations and the macro step; today's is the explicit fixed step in the Jacobi or
// Gauss-Seidel order (FixedStepAlgorithm). Implicit coupling (iterations until the coupling
// residual is small, the participants rolled back to the step's start between them, Aitken or
// quasi-Newton acceleration of the inputs) and an adaptive macro step are further
// implementations of the same interface (docs/config.md#coupling-algorithms).
#pragma once

#include <cosim/link.hpp>

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "config.hpp"

namespace master {

// What an algorithm drives. Between open_step and close_step, each call to exchange is one
// round trip of a group of participants over the open step; an iteration above 0 repeats the
// step from its start (every participant of the run then has can_repeat).
class Coupling {
 public:
  virtual ~Coupling() = default;
  // Opens macro step `step` over [t0, t1].
  virtual void open_step(int64_t step, TimePoint t0, TimePoint t1) = 0;
  // Sends every participant of `group` its inputs over the open step (the predictors' polynomials
  // from what they hold now) and hands their replies to the predictors. `checkpoint`: the
  // participants save their state after this exchange (the step's last iteration only).
  virtual void exchange(const std::vector<std::string>& group, int iteration, bool checkpoint) = 0;
  // Closes the open step after `iterations` iterations (the record's count); `checkpoint`: the
  // participants confirmed a checkpoint in it. Builds the step's record for the observers.
  virtual void close_step(int iterations, bool checkpoint) = 0;
  // Whether the participants save a checkpoint after step `step` over [t0, t1]
  // (checkpoints.every: the step reaches a multiple of it past time.start, and is not the last).
  // Asked before every attempt of a step; a step found due stays due in its redone attempts.
  virtual bool checkpoint_due(int64_t step, TimePoint t0, TimePoint t1) = 0;
  // A participant ended the run itself (an FMU's terminate) in the open step: no further
  // exchange in it and no further step.
  virtual bool ended() const = 0;

  // Implicit coupling. Per connection (config order), the value at the open step's end that is
  // in place for it now: the source's answer of the latest exchange that stepped it, one set by
  // set_end_value, or else the prediction (use: end: the polynomial at the end; use: average:
  // its mean). The fallbacks raise: an algorithm that needs these runs on a CoSimulation.
  virtual cosim::Value end_value(std::size_t connection) const;
  // Replaces the value in place at the step's end (the next exchange interpolates to it).
  virtual void set_end_value(std::size_t connection, const cosim::Value& value);
  // The open step's convergence residuals (one per coupling.convergence entry), for its record.
  virtual void set_residuals(std::vector<double> residuals);
  // The last closed step's power bonds (config `power` order): {force_side, motion_side} in W.
  virtual std::vector<std::pair<double, double>> last_power() const;

  // An adaptive step that may reject a step. hold_step: the next close_step keeps the step's
  // record back, and the predictors' state from before the step, until commit_step hands the
  // record to the observers (with the controller's error estimate and the number of attempts
  // rejected before it) or reject_step drops it and puts the predictors back; the next open_step
  // of the same step then repeats it from its start (iterations numbered on, so that every
  // participant restores its state at the step's start). The fallbacks raise.
  virtual void hold_step();
  virtual void commit_step(double step_error, int rejected);
  virtual void reject_step();
};

// What the handshake told the master, for CouplingAlgorithm::initialize.
struct AlgorithmSetup {
  const std::map<std::string, cosim::ParticipantInfo>* participants = nullptr;
  int max_order = 0;  // the highest predictor order among the connections
};

// libcosim's shape (setup, initialize, do_step returning the step taken), with the loop here.
class CouplingAlgorithm {
 public:
  virtual ~CouplingAlgorithm() = default;
  virtual std::string name() const = 0;
  // Before the handshake: takes what it needs from the config; raises ConfigError naming a key.
  virtual void setup(const Config& config) = 0;
  // After the handshake: checks the participants can do what the algorithm will ask of them
  // (repeat a step, ...); raises ConfigError naming the key and the fix.
  virtual void initialize(const AlgorithmSetup& setup) = 0;
  // Macro step `step` from `t`: drives `coupling` from open_step to close_step and returns the
  // step taken (t advances by it; a whole multiple of every participant's inner step).
  virtual Duration do_step(Coupling& coupling, int64_t step, TimePoint t) = 0;

  // The step loop: do_step from step `first_step` at `t` until t_end is reached.
  void run(Coupling& coupling, int64_t first_step, TimePoint t, TimePoint t_end);
  // The length of the next steps (an adaptive step sets it before each do_step). Fixed-step
  // algorithms take it; the default refuses.
  virtual void set_step(Duration step);
  // The step do_step just did was rejected (an adaptive step redoes it shorter): the
  // algorithm's state is put back to before it (IQN-ILS's reused columns, counters).
  virtual void forget_step() {}
  // What a resumed run needs to continue as the uninterrupted one would (the state after the
  // last step: IQN-ILS's reused columns, the adaptive step's next length and last error), as
  // text with exact (hexadecimal) numbers; "" for none. restore_state takes it back after
  // initialize; it raises std::runtime_error for text it cannot read.
  virtual std::string save_state() const { return {}; }
  virtual void restore_state(const std::string& state);
  // Whether macro step `step` may be done again from its start (a larger iteration of it, or a
  // rejected attempt redone), asked after initialize. false lets the participants skip keeping
  // the state at its start (step_request_t.no_redo); the default, true, is always safe.
  virtual bool may_repeat(int64_t step) const { return true; }
};

// The explicit fixed-step scheme: every macro step once, Jacobi (all participants in one
// group, in parallel) or Gauss-Seidel (one group per participant, in `order`). The first
// steps, whose predictors hold too few samples for their order, are iterated
// startup_iterations times more when every participant can repeat a step.
class FixedStepAlgorithm final : public CouplingAlgorithm {
 public:
  std::string name() const override;
  void setup(const Config& config) override;
  void initialize(const AlgorithmSetup& setup) override;
  Duration do_step(Coupling& coupling, int64_t step, TimePoint t) override;
  void set_step(Duration step) override { macro_step_ = step; }
  // Only the start-up steps are iterated (step < the highest predictor order, with
  // startup_iterations > 0 and every participant able to repeat): every later step runs once.
  bool may_repeat(int64_t step) const override {
    return can_iterate_ && startup_iterations_ > 0 && step < max_order_;
  }
  const std::vector<std::vector<std::string>>& groups() const { return groups_; }

 private:
  Scheme scheme_ = Scheme::Jacobi;
  Duration macro_step_{};
  int startup_iterations_ = 0;
  std::vector<std::vector<std::string>> groups_;  // participants stepping together, in turn
  int max_order_ = 0;
  bool can_iterate_ = false;  // every participant can repeat a step
};

// Implicit coupling (coupling.type: implicit): every macro step iterated, in the Jacobi or
// Gauss-Seidel order, until each coupling.convergence measure is met (at least min_iterations,
// at most max_iterations), every participant repeating the step from its start in each
// iteration after the first. Between iterations the fed-back connections' end values (Jacobi:
// every connection; Gauss-Seidel: those into a participant that steps no later than their
// source) are set by the acceleration. The first steps (predictor history too short) take at
// least 1 + startup_iterations iterations, as the explicit scheme's start-up does.
class ImplicitAlgorithm final : public CouplingAlgorithm {
 public:
  ImplicitAlgorithm();
  ~ImplicitAlgorithm() override;
  std::string name() const override;
  void setup(const Config& config) override;
  void initialize(const AlgorithmSetup& setup) override;
  Duration do_step(Coupling& coupling, int64_t step, TimePoint t) override;
  void set_step(Duration step) override { macro_step_ = step; }
  void forget_step() override;
  std::string save_state() const override;
  void restore_state(const std::string& state) override;

  const std::vector<std::size_t>& fed_back() const { return fed_back_; }
  // Accepted steps and their iterations (a rejected attempt's are in rejected_iterations).
  int64_t steps() const { return steps_; }
  int64_t total_iterations() const { return total_iterations_; }
  int64_t unconverged_steps() const { return unconverged_; }
  int64_t rejected_iterations() const { return rejected_iterations_; }

 private:
  Scheme scheme_ = Scheme::Jacobi;
  Duration macro_step_{};
  int startup_iterations_ = 0;
  CouplingSpec spec_;
  std::vector<std::string> connection_names_;  // `to` of each connection
  std::vector<std::vector<std::string>> groups_;
  std::vector<std::size_t> fed_back_;  // connections the acceleration sets
  std::vector<double> scale_;          // per fed-back connection: the largest rms value seen
  std::vector<double> scale_before_;   // ... before the last step (forget_step)
  int last_iterations_ = 0;
  bool last_unconverged_ = false;
  int64_t rejected_iterations_ = 0;
  std::unique_ptr<class Acceleration> acceleration_;
  int max_order_ = 0;
  int64_t steps_ = 0, total_iterations_ = 0, unconverged_ = 0;
};

// An adaptive macro step (coupling.adaptive) around a fixed-step algorithm (explicit or
// implicit): before each step it sets the step length, after it it measures the power bonds'
// energy residual and chooses the next length with ECCO's PI controller (docs/coupling.md).
// Every length is a whole multiple of every participant's inner step, within [min_step,
// max_step] (rounded inwards to such multiples), and the last step ends at time.end. With
// reject_above a step whose error estimate exceeds it is rolled back and redone shorter.
class AdaptiveStepAlgorithm final : public CouplingAlgorithm {
 public:
  explicit AdaptiveStepAlgorithm(std::unique_ptr<CouplingAlgorithm> inner);
  std::string name() const override;
  void setup(const Config& config) override;
  void initialize(const AlgorithmSetup& setup) override;
  Duration do_step(Coupling& coupling, int64_t step, TimePoint t) override;
  std::string save_state() const override;
  void restore_state(const std::string& state) override;
  // A step may be rejected and redone (reject_above > 0), or the inner algorithm may repeat it.
  bool may_repeat(int64_t step) const override { return spec_.reject_above > 0 || inner_->may_repeat(step); }

  struct Record {
    TimePoint t_start;
    Duration step;
    double error;  // the controller's error estimate (<= 1: within tolerance)
    bool rejected = false;  // rolled back and redone shorter (coupling.adaptive.reject_above)
  };
  // Every attempt, rejected ones included, in order.
  const std::vector<Record>& history() const { return history_; }
  Duration quantum() const { return quantum_; }
  Duration min_step() const { return min_; }
  int64_t rejected() const { return rejected_; }

 private:
  // H shortened, or lengthened to the rest of the run, so that what is left after it is nothing
  // or at least min_step.
  Duration fit(Duration H, TimePoint t) const;
  std::unique_ptr<CouplingAlgorithm> inner_;
  AdaptiveSpec spec_;
  TimePoint t_end_{};
  Duration next_{}, quantum_{}, min_{}, max_{};
  double wanted_ = 0;  // s: the controller's step, of which next_ is the largest multiple of the quantum
  double previous_error_ = 1.0;
  std::vector<Record> history_;
  int64_t rejected_ = 0;
};

// The algorithm a config asks for (FixedStepAlgorithm, or ImplicitAlgorithm for coupling.type:
// implicit), wrapped in AdaptiveStepAlgorithm with coupling.adaptive, not set up yet.
std::unique_ptr<CouplingAlgorithm> make_algorithm(const Config& config);

}  // namespace master
