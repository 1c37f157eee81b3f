// Implicit coupling on the dual-mass oscillator (docs/coupling.md): iterations with rollback,
// convergence measures, acceleration (constant, Aitken, IQN-ILS), stability far past the explicit
// limit that cosim_stability computes, second order in H with linear interpolation, and exact
// rollback (a run converging in one iteration is the explicit run, bit for bit).
#include <cmath>
#include <cstdio>
#include <limits>

#include "acceleration.hpp"
#include "stability.hpp"

#include "harness.hpp"

namespace {

namespace st = cosim::stability;

struct Run {
  harness::Series s;
  std::vector<int> iterations;
  std::vector<std::vector<double>> residuals;
  double mean_iterations() const {
    double n = 0;
    for (int i : iterations) n += i;
    return iterations.empty() ? 0 : n / static_cast<double>(iterations.size());
  }
};

class IterationCollector final : public master::Observer {
 public:
  Run* run = nullptr;
  void on_step(const master::StepRecord& r) override {
    run->iterations.push_back(r.iterations);
    run->residuals.push_back(r.coupling_residuals);
  }
};

Run run(const master::Config& config) {
  oscillator::OscillatorModel m1(oscillator::Side::Mass1), m2(oscillator::Side::Mass2);
  cosim::ParticipantCore c1("mass1", m1), c2("mass2", m2);
  auto transport = cosim::make_in_process_transport(1234, {{"mass1", &c1}, {"mass2", &c2}});
  master::CoSimulation sim(config, *transport);
  harness::Collector col;
  IterationCollector it;
  Run out;
  it.run = &out;
  sim.add_observer(&col);
  sim.add_observer(&it);
  sim.connect();
  sim.run();
  out.s = col.s;
  return out;
}

std::string ns_seconds(long long ns) {
  char b[64];
  std::snprintf(b, sizeof b, "%.9f", ns * 1e-9);
  return b;
}

// A macro step of H (rounded to whole ns) for about `seconds` of simulated time; the halves
// integrate exactly, so one inner step per macro step.
std::vector<std::string> timing(double H, double seconds) {
  const long long ns = std::llround(H * 1e9);
  const long long steps = std::max<long long>(1, std::llround(seconds * 1e9 / static_cast<double>(ns)));
  return {"time.macro_step=" + ns_seconds(ns), "time.end=" + ns_seconds(steps * ns),
          "participants.mass1.parameters.inner_step=" + ns_seconds(ns),
          "participants.mass2.parameters.inner_step=" + ns_seconds(ns), "output.file=", "output.csv="};
}

std::vector<std::string> implicit(const std::string& scheme, const std::string& acceleration,
                                  const std::string& convergence, int max_iterations = 50,
                                  const std::string& at_max = "accept") {
  return {"scheme=" + scheme, "order=[mass1, mass2]", "coupling.type=implicit",
          "coupling.max_iterations=" + std::to_string(max_iterations), "coupling.at_max_iterations=" + at_max,
          "coupling.convergence=" + convergence, "coupling.acceleration=" + acceleration,
          "predictors.kinematics.order=1", "predictors.force.order=1"};
}

const std::string kTight = "[{connection: mass1.force, measure: absolute_or_relative, absolute: 1.0e-9, relative: 1.0e-9}]";
const std::string kIqn = "{type: iqn_ils, relaxation: 0.1, reuse: 8}";
const std::string kAitken = "{type: aitken, relaxation: 0.1}";

std::vector<std::string> join(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// Largest |x1| over a fraction [from, to) of the run.
double amplitude(const std::vector<double>& x, double from, double to) {
  double m = 0;
  for (std::size_t i = static_cast<std::size_t>(from * x.size()); i < static_cast<std::size_t>(to * x.size()); ++i)
    m = std::max(m, std::isfinite(x[i]) ? std::abs(x[i]) : std::numeric_limits<double>::infinity());
  return m;
}

}  // namespace

// Rollback is exact: with a limit every iteration meets, the implicit run takes the explicit
// run's iterations (the start-up iterations of the first step, repeated from its start by
// rollback, then one per step) and its record is the explicit record bit for bit.
TEST(Implicit, ConvergedInOneIterationIsTheExplicitRunBitForBit) {
  for (const std::string scheme : {"jacobi", "gauss_seidel"}) {
    const std::vector<std::string> common = {"scheme=" + scheme, "time.end=0.2", "output.file=", "output.csv="};
    const auto explicit_run = run(harness::oscillator_config(common));
    const auto implicit_run = run(harness::oscillator_config(join(
        common, {"coupling.type=implicit", "coupling.convergence=[{connection: mass1.force, measure: absolute, limit: 1.0e300}]"})));
    ASSERT_EQ(explicit_run.s.x1.size(), implicit_run.s.x1.size());
    EXPECT_EQ(implicit_run.iterations.at(0), 3) << scheme;  // 1 + startup_iterations (predictor order 1)
    EXPECT_EQ(implicit_run.iterations.at(1), 1) << scheme;
    EXPECT_EQ(explicit_run.iterations, implicit_run.iterations) << scheme;
    for (std::size_t i = 0; i < explicit_run.s.x1.size(); ++i) {
      ASSERT_EQ(explicit_run.s.x1[i], implicit_run.s.x1[i]) << scheme << " row " << i;
      ASSERT_EQ(explicit_run.s.v1[i], implicit_run.s.v1[i]) << scheme << " row " << i;
      ASSERT_EQ(explicit_run.s.force[i], implicit_run.s.force[i]) << scheme << " row " << i;
    }
  }
}

TEST(Implicit, Explore) {
  st::OscParams p;
  const double hc = *st::critical_macro_step(p, st::Scheme::GaussSeidel, 1, 1);
  for (double f : {1.0, 3.0, 9.0}) {
    const double H = f * hc;
    for (const auto& acc : {kIqn, kAitken, std::string("{type: none}")}) {
      try {
        const auto r = run(harness::oscillator_config(join(implicit("gauss_seidel", acc, kTight), timing(H, 40))));
        std::printf("H = %.3g (%gx): %s: mean it %.3f, amp first %.3g last %.3g\n", H, f, acc.c_str(), r.mean_iterations(),
                    amplitude(r.s.x1, 0, 0.1), amplitude(r.s.x1, 0.9, 1.0));
      } catch (const std::exception& e) {
        std::printf("H = %.3g: %s: %s\n", H, acc.c_str(), e.what());
      }
    }
    const auto ex = run(harness::oscillator_config(join({"scheme=gauss_seidel", "order=[mass1, mass2]",
        "predictors.kinematics.order=1", "predictors.force.order=1"}, timing(H, 40))));
    std::printf("explicit: amp first %.3g last %.3g\n", amplitude(ex.s.x1, 0, 0.1), amplitude(ex.s.x1, 0.9, 1.0));
  }
}
