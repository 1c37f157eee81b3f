// The coupling-algorithm interface (master/src/coupling_algorithm.hpp): what FixedStepAlgorithm
// asks of the master, call by call, for Jacobi and Gauss-Seidel, with start-up iterations and
// checkpoints; the step loop; the refusal of start-up iterations a participant cannot do; and an
// algorithm of a test's own driving CoSimulation in process (the interface is what the master
// runs, not a side door).
#include <gtest/gtest.h>

#include <cosim/participant_core.hpp>

#include "config.hpp"
#include "cosimulation.hpp"
#include "coupling_algorithm.hpp"
#include "oscillator_adapter.hpp"

namespace {

const std::string kSource = SOURCE_DIR;

master::Config config(std::vector<std::string> overrides) {
  overrides.push_back("output.file=");
  overrides.push_back("output.csv=");
  return master::load_config(kSource + "/configs/oscillator.yaml", overrides);
}

// Writes down every call, one line each.
class Script final : public master::Coupling {
 public:
  std::vector<std::string> calls;
  int64_t checkpoint_every = 0;  // steps; 0: none
  void open_step(int64_t step, master::TimePoint t0, master::TimePoint t1) override {
    calls.push_back("open " + std::to_string(step) + " " + std::to_string(cosim::to_ns(t0)) + ".." +
                    std::to_string(cosim::to_ns(t1)));
  }
  void exchange(const std::vector<std::string>& group, int iteration, bool checkpoint) override {
    std::string g;
    for (const auto& n : group) g += (g.empty() ? "" : ",") + n;
    calls.push_back("exchange " + g + " it " + std::to_string(iteration) + (checkpoint ? " checkpoint" : ""));
  }
  void close_step(int iterations, bool checkpoint) override {
    calls.push_back("close " + std::to_string(iterations) + (checkpoint ? " checkpoint" : ""));
  }
  bool checkpoint_due(int64_t step, master::TimePoint, master::TimePoint) override {
    return checkpoint_every > 0 && (step + 1) % checkpoint_every == 0;
  }
  bool ended() const override { return false; }
};

std::map<std::string, cosim::ParticipantInfo> participants(bool can_repeat) {
  std::map<std::string, cosim::ParticipantInfo> p;
  for (const char* n : {"mass1", "mass2"}) {
    p[n].can_repeat = can_repeat;
    if (!can_repeat) p[n].repeat_note = "no snapshots";
  }
  return p;
}

}  // namespace

TEST(CouplingAlgorithm, JacobiIteratesTheFirstStepsAndCheckpointsTheLastIteration) {
  const auto c = config({"time.end=2e-3", "time.macro_step=5e-4", "startup_iterations=2"});
  master::FixedStepAlgorithm a;
  a.setup(c);
  const auto p = participants(true);
  a.initialize({&p, 1});
  EXPECT_EQ(a.name(), "fixed step (Jacobi)");
  Script s;
  s.checkpoint_every = 1;
  a.run(s, 0, c.t_start, c.t_end);
  const std::vector<std::string> expected{
      "open 0 0..500000", "exchange mass1,mass2 it 0", "exchange mass1,mass2 it 1",
      "exchange mass1,mass2 it 2 checkpoint", "close 3 checkpoint",
      "open 1 500000..1000000", "exchange mass1,mass2 it 0 checkpoint", "close 1 checkpoint",
      "open 2 1000000..1500000", "exchange mass1,mass2 it 0 checkpoint", "close 1 checkpoint",
      "open 3 1500000..2000000", "exchange mass1,mass2 it 0 checkpoint", "close 1 checkpoint"};
  EXPECT_EQ(s.calls, expected);
}

TEST(CouplingAlgorithm, GaussSeidelStepsTheGroupsInOrderAndResumesMidRun) {
  const auto c = config({"time.end=2e-3", "time.macro_step=5e-4", "scheme=gauss_seidel", "order=[mass2, mass1]",
                         "predictors.force.order=2"});
  master::FixedStepAlgorithm a;
  a.setup(c);
  const auto p = participants(true);
  a.initialize({&p, 2});
  EXPECT_EQ(a.name(), "fixed step (Gauss-Seidel)");
  Script s;
  a.run(s, 2, c.t_start + 2 * c.macro_step, c.t_end);  // a resumed run: steps 2 and 3 are left
  const std::vector<std::string> expected{
      "open 2 1000000..1500000", "exchange mass2 it 0", "exchange mass1 it 0", "close 1",
      "open 3 1500000..2000000", "exchange mass2 it 0", "exchange mass1 it 0", "close 1"};
  EXPECT_EQ(s.calls, expected);
}

TEST(CouplingAlgorithm, StartupIterationsNeedParticipantsThatCanRepeatAStep) {
  master::FixedStepAlgorithm a;
  a.setup(config({"startup_iterations=2"}));
  const auto cannot = participants(false);
  try {
    a.initialize({&cannot, 1});
    FAIL() << "refused";
  } catch (const cosim::config::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot repeat a step (no snapshots)"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(a.initialize({&cannot, 0}));  // order 0: nothing to iterate
  master::FixedStepAlgorithm b;
  b.setup(config({"startup_iterations=0"}));
  EXPECT_NO_THROW(b.initialize({&cannot, 1}));
  // And without repeats the first steps run once.
  Script s;
  b.do_step(s, 0, master::TimePoint{});
  EXPECT_EQ(s.calls.back(), "close 1");
}

// A step loop that gets a step of zero length stops instead of spinning.
TEST(CouplingAlgorithm, AStepOfZeroLengthStopsTheLoop) {
  class Stuck final : public master::CouplingAlgorithm {
   public:
    std::string name() const override { return "stuck"; }
    void setup(const master::Config&) override {}
    void initialize(const master::AlgorithmSetup&) override {}
    master::Duration do_step(master::Coupling&, int64_t, master::TimePoint) override { return {}; }
  } stuck;
  Script s;
  EXPECT_THROW(stuck.run(s, 0, master::TimePoint{}, master::TimePoint{} + std::chrono::seconds(1)), std::logic_error);
}

// An algorithm given to CoSimulation runs the co-simulation: here the fixed step wrapped by
// one that counts its calls; the records equal the default algorithm's.
TEST(CouplingAlgorithm, AnAlgorithmGivenToCoSimulationRunsIt) {
  class Counting final : public master::CouplingAlgorithm {
   public:
    int steps = 0;
    master::FixedStepAlgorithm inner;
    std::string name() const override { return "counting"; }
    void setup(const master::Config& c) override { inner.setup(c); }
    void initialize(const master::AlgorithmSetup& s) override { inner.initialize(s); }
    master::Duration do_step(master::Coupling& c, int64_t step, master::TimePoint t) override {
      ++steps;
      return inner.do_step(c, step, t);
    }
  };
  class Rows final : public master::Observer {
   public:
    std::vector<double> x;
    void on_step(const master::StepRecord& r) override { x.push_back(r.outputs.at("mass1").at("x").value[0]); }
  };
  const auto c = config({"time.end=0.05"});
  auto run = [&](std::unique_ptr<master::CouplingAlgorithm> algorithm, Rows& rows) {
    oscillator::OscillatorAdapter m1(oscillator::Side::Mass1), m2(oscillator::Side::Mass2);
    cosim::ParticipantCore c1("mass1", m1), c2("mass2", m2);
    auto transport = cosim::make_in_process_transport(1234, {{"mass1", &c1}, {"mass2", &c2}});
    master::CoSimulation sim(c, *transport, std::move(algorithm));
    sim.add_observer(&rows);
    sim.connect();
    sim.run();
    return sim.algorithm().name();
  };
  auto counting = std::make_unique<Counting>();
  Counting* counted = counting.get();
  Rows a, b;
  EXPECT_EQ(run(std::move(counting), a), "counting");
  EXPECT_EQ(counted->steps, 100);
  EXPECT_EQ(run(nullptr, b), "fixed step (Jacobi)");
  ASSERT_EQ(a.x.size(), 100u);
  EXPECT_EQ(a.x, b.x);
}

// Which steps may be redone (step_request_t.no_redo is sent for the others): the fixed step
// iterates only the start-up steps, below the highest predictor order, with startup_iterations
// and participants that can repeat. In a co-simulation the participants then keep a snapshot
// only of those steps' starts, with the same records as when every step keeps one.
TEST(CouplingAlgorithm, OnlyTheStartupStepsMayBeRedoneAndTheOthersKeepNoSnapshot) {
  master::FixedStepAlgorithm a;
  a.setup(config({"startup_iterations=2"}));
  const auto can = participants(true), cannot = participants(false);
  a.initialize({&can, 2});
  EXPECT_TRUE(a.may_repeat(0));
  EXPECT_TRUE(a.may_repeat(1));
  EXPECT_FALSE(a.may_repeat(2));
  EXPECT_FALSE(a.may_repeat(1000));
  a.initialize({&can, 0});  // order 0: nothing to iterate
  EXPECT_FALSE(a.may_repeat(0));
  master::FixedStepAlgorithm b;
  b.setup(config({"startup_iterations=0"}));
  b.initialize({&can, 1});
  EXPECT_FALSE(b.may_repeat(0));
  b.initialize({&cannot, 1});
  EXPECT_FALSE(b.may_repeat(0));

  // The oscillator's halves, counting the snapshots kept and skipped.
  class Spy final : public cosim::Model {
   public:
    explicit Spy(oscillator::Side side) : m(side) {}
    oscillator::OscillatorAdapter m;
    int saves = 0, skips = 0;
    void configure(const YAML::Node& p, const cosim::RunInfo& r) override { m.configure(p, r); }
    cosim::Ports inputs() const override { return m.inputs(); }
    cosim::Ports outputs() const override { return m.outputs(); }
    cosim::Duration inner_step() const override { return m.inner_step(); }
    cosim::Signals initial_outputs() override { return m.initial_outputs(); }
    cosim::StepResult step(const cosim::StepInputs& in, bool avg) override { return m.step(in, avg); }
    bool can_repeat() const override { return true; }
    void save_snapshot() override { ++saves, m.save_snapshot(); }
    void restore_snapshot() override { m.restore_snapshot(); }
    void skip_snapshot() override { ++skips; }
  };
  // The fixed step as an algorithm that does not say which steps repeat (the default: all may).
  class Cautious final : public master::CouplingAlgorithm {
   public:
    master::FixedStepAlgorithm inner;
    std::string name() const override { return "cautious"; }
    void setup(const master::Config& c) override { inner.setup(c); }
    void initialize(const master::AlgorithmSetup& s) override { inner.initialize(s); }
    master::Duration do_step(master::Coupling& c, int64_t step, master::TimePoint t) override {
      return inner.do_step(c, step, t);
    }
  };
  class Rows final : public master::Observer {
   public:
    std::vector<double> x, f;
    void on_step(const master::StepRecord& r) override {
      x.push_back(r.outputs.at("mass1").at("x").value[0]);
      f.push_back(r.outputs.at("mass2").at("force").value[0]);
    }
  };
  // Order 2 for the force: the first two steps are iterated.
  const auto c = config({"time.end=0.05", "startup_iterations=2", "predictors.force.order=2"});
  struct Run {
    Rows rows;
    int saves = 0, skips = 0;
  };
  auto run = [&](std::unique_ptr<master::CouplingAlgorithm> algorithm) {
    Run out;
    Spy m1(oscillator::Side::Mass1), m2(oscillator::Side::Mass2);
    cosim::ParticipantCore c1("mass1", m1), c2("mass2", m2);
    auto transport = cosim::make_in_process_transport(1234, {{"mass1", &c1}, {"mass2", &c2}});
    master::CoSimulation sim(c, *transport, std::move(algorithm));
    sim.add_observer(&out.rows);
    sim.connect();
    sim.run();
    out.saves = m1.saves + m2.saves;
    out.skips = m1.skips + m2.skips;
    return out;
  };
  const Run fixed = run(nullptr), cautious = run(std::make_unique<Cautious>());
  ASSERT_EQ(fixed.rows.x.size(), 100u);
  EXPECT_EQ(fixed.saves, 2 * 2);  // steps 0 and 1, both participants
  EXPECT_EQ(fixed.skips, 2 * 98);
  EXPECT_EQ(cautious.saves, 2 * 100);
  EXPECT_EQ(cautious.skips, 0);
  EXPECT_EQ(fixed.rows.x, cautious.rows.x);  // bit for bit
  EXPECT_EQ(fixed.rows.f, cautious.rows.f);
}
