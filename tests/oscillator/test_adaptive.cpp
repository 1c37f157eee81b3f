// The adaptive macro step (coupling.adaptive, docs/coupling.md#adaptive-macro-step) on the
// dual-mass oscillator with a wall that mass1 hits: the step grows while the masses swing
// quietly in phase, shrinks at the impact, never leaves its bounds, is always a whole multiple
// of every inner step, and the steps add up to time.end exactly; with explicit and implicit
// coupling.
#include <cmath>
#include <cstdio>

#include "harness.hpp"

namespace {

using cosim::Duration;

// mass1 of the oscillator with a stiff one-sided wall: m x'' = -c x - d v + F + k_w (wall - x)
// while x < wall. Integrated with RK4 at its inner step on the force polynomial.
class WallMass final : public cosim::Model {
 public:
  void configure(const YAML::Node& n, const cosim::RunInfo&) override {
    namespace cfg = cosim::config;
    cfg::check_keys(n, "parameters", {"mass", "stiffness", "damping", "position", "velocity", "inner_step", "wall",
                                      "wall_stiffness"});
    m_ = cfg::get_positive(n, "parameters", "mass");
    c_ = cfg::get_double(n, "parameters", "stiffness");
    d_ = cfg::get_double(n, "parameters", "damping");
    x_ = cfg::get_double(n, "parameters", "position");
    v_ = cfg::get_double(n, "parameters", "velocity");
    wall_ = cfg::get_double(n, "parameters", "wall");
    kw_ = cfg::get_positive(n, "parameters", "wall_stiffness");
    inner_ = cosim::seconds_to_duration(cfg::get_positive(n, "parameters", "inner_step"), "inner_step");
  }
  cosim::Ports inputs() const override { return {{"force", cosim::SignalKind::Scalar}}; }
  cosim::Ports outputs() const override { return {{"x", cosim::SignalKind::Scalar}, {"v", cosim::SignalKind::Scalar}}; }
  Duration inner_step() const override { return inner_; }
  cosim::Signals initial_outputs() override { return signals(); }
  cosim::StepResult step(const cosim::StepInputs& in, bool) override {
    const double h = cosim::to_seconds(inner_);
    for (auto t = in.t_start(); t < in.t_end(); t += inner_) {
      const double F0 = in.at("force", t)[0], F1 = in.at("force", t + inner_ / 2)[0], F2 = in.at("force", t + inner_)[0];
      auto a = [&](double x, double v, double F) {
        return (-c_ * x - d_ * v + F + (x < wall_ ? kw_ * (wall_ - x) : 0.0)) / m_;
      };
      const double k1x = v_, k1v = a(x_, v_, F0);
      const double k2x = v_ + 0.5 * h * k1v, k2v = a(x_ + 0.5 * h * k1x, v_ + 0.5 * h * k1v, F1);
      const double k3x = v_ + 0.5 * h * k2v, k3v = a(x_ + 0.5 * h * k2x, v_ + 0.5 * h * k2v, F1);
      const double k4x = v_ + h * k3v, k4v = a(x_ + h * k3x, v_ + h * k3v, F2);
      x_ += h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x);
      v_ += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
    }
    cosim::StepResult r;
    r.outputs = signals();
    return r;
  }
  bool can_repeat() const override { return true; }
  void save_snapshot() override { saved_ = {x_, v_}; }
  void restore_snapshot() override { x_ = saved_.first, v_ = saved_.second; }

 private:
  cosim::Signals signals() const {
    return {{"x", {cosim::SignalKind::Scalar, {x_}}}, {"v", {cosim::SignalKind::Scalar, {v_}}}};
  }
  double m_ = 1, c_ = 0, d_ = 0, x_ = 0, v_ = 0, wall_ = 0, kw_ = 0;
  Duration inner_{};
  std::pair<double, double> saved_;
};

struct Result {
  harness::Series s;
  std::vector<master::AdaptiveStepAlgorithm::Record> history;  // rejected attempts included
  Duration quantum{};
  std::string name;
  std::vector<master::StepRecord> records;  // what the observers got (no outputs kept)
};

// Keeps each step record's times, error and counts.
class Steps final : public master::Observer {
 public:
  std::vector<master::StepRecord> records;
  void on_step(const master::StepRecord& r) override {
    master::StepRecord k;
    k.step_index = r.step_index, k.t_start = r.t_start, k.t_end = r.t_end, k.iterations = r.iterations;
    k.step_error = r.step_error, k.rejected = r.rejected;
    records.push_back(k);
  }
};

// Fixed-step macro steps of given lengths, one after another: the accepted steps of an
// adaptive run replayed without any rejection.
// Explicit or implicit as the config says.
class GivenSteps final : public master::CouplingAlgorithm {
 public:
  explicit GivenSteps(std::vector<Duration> steps) : steps_(std::move(steps)) {}
  std::string name() const override { return "given steps"; }
  void setup(const master::Config& c) override {
    if (c.coupling.type == master::CouplingType::Implicit) inner_ = std::make_unique<master::ImplicitAlgorithm>();
    else inner_ = std::make_unique<master::FixedStepAlgorithm>();
    inner_->setup(c);
  }
  void initialize(const master::AlgorithmSetup& s) override { inner_->initialize(s); }
  Duration do_step(master::Coupling& coupling, int64_t step, cosim::TimePoint t) override {
    inner_->set_step(steps_.at(static_cast<std::size_t>(step)));
    return inner_->do_step(coupling, step, t);
  }

 private:
  std::unique_ptr<master::CouplingAlgorithm> inner_;
  std::vector<Duration> steps_;
};

master::Config wall_config(std::vector<std::string> extra) {
  std::vector<std::string> o = {
      "time.end=2.0", "time.macro_step=1.0e-3", "output.file=", "output.csv=",
      "participants.mass1.parameters={mass: 1, stiffness: 10, damping: 0.2, position: 0.1, velocity: 0, "
      "inner_step: 1.0e-5, wall: -0.05, wall_stiffness: 1.0e5}",
      // mass2 starts beside mass1 (coupling spring relaxed): the in-phase swing, quiet until the wall
      "participants.mass2.parameters.position=0.1", "participants.mass2.parameters.coupled_position=0.1",
      "participants.mass2.parameters.inner_step=2.0e-5",
      "coupling.adaptive={min_step: 1.0e-4, max_step: 2.0e-2, abs_tolerance: 1.0e-6, rel_tolerance: 1.0e-3}"};
  o.insert(o.end(), extra.begin(), extra.end());
  return harness::oscillator_config(o);
}

// The wall scene with `algorithm` (null: the config's).
Result run_with(const master::Config& config, std::unique_ptr<master::CouplingAlgorithm> algorithm) {
  WallMass m1;
  oscillator::OscillatorAdapter m2(oscillator::Side::Mass2);
  cosim::ParticipantCore c1("mass1", m1), c2("mass2", m2);
  auto transport = cosim::make_in_process_transport(1234, {{"mass1", &c1}, {"mass2", &c2}});
  master::CoSimulation sim(config, *transport, std::move(algorithm));
  harness::Collector col;
  Steps steps;
  sim.add_observer(&col);
  sim.add_observer(&steps);
  sim.connect();
  sim.run();
  Result r{col.s, {}, {}, sim.algorithm().name(), steps.records};
  if (const auto* a = dynamic_cast<const master::AdaptiveStepAlgorithm*>(&sim.algorithm()))
    r.history = a->history(), r.quantum = a->quantum();
  return r;
}

Result run(std::vector<std::string> extra) { return run_with(wall_config(std::move(extra)), nullptr); }

void check(const Result& r) {
  SCOPED_TRACE(r.name);
  ASSERT_FALSE(r.history.empty());
  EXPECT_EQ(r.quantum, Duration(20000));  // lcm(10 us, 20 us) in ns
  // Bounds and quanta: min_step 1e-4 and max_step 2e-2 are multiples of 20 us already.
  Duration total{};
  for (const auto& h : r.history) {
    EXPECT_GE(h.step, Duration(100000));
    EXPECT_LE(h.step, Duration(20000000));
    EXPECT_EQ(h.step % r.quantum, Duration::zero());
    if (!h.rejected) total += h.step;
  }
  EXPECT_EQ(total, Duration(2000000000));  // integer nanoseconds: exactly time.end
  // The impact: the first macro time with x1 below the wall.
  std::size_t hit = 0;
  while (hit < r.s.x1.size() && r.s.x1[hit] >= -0.05) ++hit;
  ASSERT_LT(hit, r.s.x1.size()) << "mass1 never reached the wall";
  const double t_hit = r.s.t[hit];
  // Quiet phase: from 1 ms the step grows to at least 4 ms well before the impact.
  Duration quiet_max{}, before_hit{}, around_min = Duration::max();
  for (const auto& h : r.history) {
    if (h.rejected) continue;
    const double t = cosim::to_seconds(h.t_start.time_since_epoch());
    if (t < t_hit - 0.1) quiet_max = std::max(quiet_max, h.step);
    if (t < t_hit - 0.05) before_hit = h.step;
    if (t > t_hit - 0.05 && t < t_hit + 0.05) around_min = std::min(around_min, h.step);
  }
  std::printf("%s: impact at t = %.4f s; steps: quiet max %.4g s, just before %.4g s, smallest around the impact %.4g s; %zu steps\n",
              r.name.c_str(), t_hit, cosim::to_seconds(quiet_max), cosim::to_seconds(before_hit),
              cosim::to_seconds(around_min), r.records.size());
  EXPECT_GE(quiet_max, Duration(4000000)) << "the step should grow in the quiet phase";
  EXPECT_LE(around_min * 4, before_hit) << "the step should shrink at the impact";
}

}  // namespace

TEST(AdaptiveStep, GrowsWhenQuietShrinksAtTheImpactStaysInBoundsExplicit) {
  check(run({"scheme=gauss_seidel", "order=[mass1, mass2]"}));
  check(run({"scheme=jacobi"}));
}

// A step of one quantum grows: the controller's step is continuous and the taken step the largest
// multiple of the quantum below it, so a growth factor under 2 adds up over steps (rounding the
// taken step down and growing that held it at one quantum forever: the wheel loader stayed at
// min_step = the DEM step in the pile, docs/coupling.md).
TEST(AdaptiveStep, GrowsFromOneQuantum) {
  for (const std::string scheme : {"scheme=jacobi", "scheme=gauss_seidel"}) {
    const auto r = run({scheme, "order=[mass1, mass2]", "time.macro_step=2.0e-5", "time.end=0.5",
                        "coupling.adaptive={min_step: 2.0e-5, max_step: 2.0e-2, abs_tolerance: 1.0e-6, "
                        "rel_tolerance: 1.0e-3}"});
    SCOPED_TRACE(r.name);
    ASSERT_GE(r.history.size(), 3u);
    EXPECT_EQ(r.history.front().step, Duration(20000));  // one quantum
    Duration largest{}, total{};
    for (std::size_t i = 0; i < r.history.size(); ++i) {
      const auto& h = r.history[i];
      EXPECT_EQ(h.step % r.quantum, Duration::zero());
      largest = std::max(largest, h.step);
      total += h.step;
      // No faster than max_change (1.5) per step on the controller's step, which is less than a
      // quantum above the step taken before.
      if (i > 0) {
        EXPECT_LE(cosim::to_seconds(h.step), 1.5 * (cosim::to_seconds(r.history[i - 1].step) + 2e-5) + 1e-12) << i;
      }
    }
    EXPECT_EQ(total, Duration(500000000));
    // In the quiet swing (no impact before 0.69 s) the step reaches several ms, as from 1 ms.
    std::printf("%s: from one quantum (20 us): largest step %.4g s, %zu steps in 0.5 s\n", r.name.c_str(),
                cosim::to_seconds(largest), r.history.size());
    EXPECT_GE(largest, Duration(2000000));
  }
}

TEST(AdaptiveStep, WorksWithImplicitCoupling) {
  check(run({"scheme=gauss_seidel", "order=[mass1, mass2]", "coupling.type=implicit",
             "coupling.convergence=[{connection: mass1.force, measure: absolute_or_relative, absolute: 1.0e-9, relative: 1.0e-9}]",
             "coupling.acceleration={type: iqn_ils, relaxation: 0.1, reuse: 8}"}));
}

// coupling.adaptive.reject_above: a step whose error estimate is above it is rolled back and redone
// shorter. Checked: steps are rejected at the impact; every accepted step longer than min_step
// is within the threshold; each redo is shorter than the attempt it replaces and starts at the
// same time; the record has the accepted steps only, each with its error and its count of
// rejected attempts; the steps still add up to time.end exactly in whole quanta; and the
// rollback is exact: the accepted step lengths replayed by a fixed-step algorithm (no
// rejection) give the same trajectory bit for bit (participants and predictors restored).
void check_rejection(const std::vector<std::string>& extra, double reject_above) {
  auto options = extra;
  options.push_back("coupling.adaptive.reject_above=" + std::to_string(reject_above));
  const auto config = wall_config(options);
  const Result r = run_with(config, nullptr);
  check(r);
  SCOPED_TRACE(r.name);
  const Duration min_step(100000);
  std::vector<Duration> accepted;
  int64_t rejected = 0, rejected_at_impact = 0;
  double worst_accepted = 0;
  for (std::size_t i = 0; i < r.history.size(); ++i) {
    const auto& h = r.history[i];
    if (h.rejected) {
      ++rejected;
      EXPECT_TRUE(!(h.error <= reject_above)) << "a step within the threshold was rejected";
      EXPECT_GT(h.step, min_step) << "a step at min_step cannot be shortened, so it is not rejected";
      ASSERT_LT(i + 1, r.history.size());
      EXPECT_EQ(r.history[i + 1].t_start, h.t_start) << "the redo starts where the rejected attempt did";
      EXPECT_LT(r.history[i + 1].step, h.step) << "the redo is shorter";
      const double t = cosim::to_seconds(h.t_start.time_since_epoch());
      if (t > 0.6 && t < 0.8) ++rejected_at_impact;
      continue;
    }
    accepted.push_back(h.step);
    if (h.step > min_step) {
      EXPECT_LE(h.error, reject_above) << "accepted above the threshold at t = "
                                       << cosim::to_seconds(h.t_start.time_since_epoch());
      worst_accepted = std::max(worst_accepted, h.error);
    }
  }
  std::printf("%s, reject_above %g: %lld attempts rejected (%lld at the impact, 0.6-0.8 s), %zu accepted, "
              "largest accepted error above min_step %.3g\n",
              r.name.c_str(), reject_above, static_cast<long long>(rejected), static_cast<long long>(rejected_at_impact),
              accepted.size(), worst_accepted);
  EXPECT_GT(rejected_at_impact, 0) << "the impact should reject steps";
  // The record: the accepted steps only, contiguous, with their rejected attempts counted.
  ASSERT_EQ(r.records.size(), accepted.size());
  int64_t counted = 0;
  for (std::size_t i = 0; i < r.records.size(); ++i) {
    EXPECT_EQ(r.records[i].step_index, static_cast<int64_t>(i));
    EXPECT_EQ(r.records[i].t_end - r.records[i].t_start, accepted[i]);
    if (i > 0) EXPECT_EQ(r.records[i].t_start, r.records[i - 1].t_end);
    EXPECT_TRUE(std::isfinite(r.records[i].step_error));
    counted += r.records[i].rejected;
  }
  EXPECT_EQ(counted, rejected);
  EXPECT_EQ(r.records.back().t_end, config.t_end);
  // Exact rollback: the same steps without rejections, bit for bit.
  auto fixed = wall_config(extra);
  const Result g = run_with(fixed, std::make_unique<GivenSteps>(accepted));
  ASSERT_EQ(g.s.t.size(), r.s.t.size());
  for (std::size_t i = 0; i < g.s.t.size(); ++i) {
    ASSERT_EQ(g.s.t[i], r.s.t[i]) << i;
    ASSERT_EQ(g.s.x1[i], r.s.x1[i]) << "row " << i;
    ASSERT_EQ(g.s.v1[i], r.s.v1[i]) << "row " << i;
    ASSERT_EQ(g.s.force[i], r.s.force[i]) << "row " << i;
  }
}

TEST(AdaptiveStep, RejectsAndRepeatsAStepAboveTheThresholdExplicit) {
  check_rejection({"scheme=gauss_seidel", "order=[mass1, mass2]"}, 2.0);
  check_rejection({"scheme=jacobi"}, 2.0);
}

TEST(AdaptiveStep, RejectsAndRepeatsWithImplicitCoupling) {
  check_rejection({"scheme=gauss_seidel", "order=[mass1, mass2]", "coupling.type=implicit",
                   "coupling.convergence=[{connection: mass1.force, measure: absolute_or_relative, absolute: 1.0e-9, relative: 1.0e-9}]",
                   "coupling.acceleration={type: iqn_ils, relaxation: 0.1, reuse: 8}"},
                  2.0);
}
