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
  oscillator::OscillatorAdapter m1(oscillator::Side::Mass1), m2(oscillator::Side::Mass2);
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
                                  const std::string& convergence, int kf, int max_iterations = 50,
                                  const std::string& at_max = "accept") {
  return {"scheme=" + scheme, "order=[mass1, mass2]", "coupling.type=implicit",
          "coupling.max_iterations=" + std::to_string(max_iterations), "coupling.at_max_iterations=" + at_max,
          "coupling.convergence=" + convergence, "coupling.acceleration=" + acceleration,
          "predictors.kinematics.order=1", "predictors.force.order=" + std::to_string(kf)};
}

std::vector<std::string> explicit_gs(int kf) {
  return {"scheme=gauss_seidel", "order=[mass1, mass2]", "predictors.kinematics.order=1",
          "predictors.force.order=" + std::to_string(kf)};
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

// Measured growth rate of x1 [1/s]: log of the amplitude ratio between the fifth and the last
// tenth of the run over the time between them.
double rate(const harness::Series& s) {
  const double a = amplitude(s.x1, 0.4, 0.5), b = amplitude(s.x1, 0.9, 1.0);
  return std::log(b / a) / (0.5 * s.t.back());
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


// Equal masses, the config's predictors (kinematics linear, force constant): implicit
// Gauss-Seidel at 9x the explicit Gauss-Seidel limit decays while the explicit run explodes.
// cosim_stability: explicit limit 8.454e-3 s, converged implicit 1.032e-1 s (12.2x).
TEST(Implicit, GaussSeidelStaysStableAtNineTimesTheExplicitLimit) {
  const double hc = *st::critical_macro_step({}, st::Scheme::GaussSeidel, 1, 0);
  const double H = 9 * hc;
  const auto ex = run(harness::oscillator_config(join(explicit_gs(0), timing(H, 40))));
  const auto im = run(harness::oscillator_config(join(implicit("gauss_seidel", kIqn, kTight, 0), timing(H, 40))));
  std::printf("equal masses, H = 9 x %.4e = %.4e s: explicit |x1| %.3g -> %.3g; implicit %.3g -> %.3g, %.2f iterations/step\n",
              hc, H, amplitude(ex.s.x1, 0, 0.1), amplitude(ex.s.x1, 0.9, 1), amplitude(im.s.x1, 0, 0.1),
              amplitude(im.s.x1, 0.9, 1), im.mean_iterations());
  EXPECT_GT(amplitude(ex.s.x1, 0.9, 1.0), 1e3) << "the explicit run should fail at 9x its limit";
  EXPECT_LT(amplitude(im.s.x1, 0.9, 1.0), 0.5 * amplitude(im.s.x1, 0, 0.1)) << "the implicit run must decay";
  EXPECT_LT(rate(im.s), 0);
}

// A light first mass (m1 = 0.01 m2): the explicit limits shrink (Jacobi 1.926e-3 s, Gauss-Seidel
// 4.498e-3 s), the converged implicit one stays near 0.1 s (9.894e-2 s): implicit Gauss-Seidel is
// stable at 25x the explicit limit of the config's scheme (Jacobi) and at 20x the explicit
// Gauss-Seidel limit; plain iteration diverges there, IQN-ILS converges in <= 2.5 iterations
// per step on average and Aitken in <= 3.5.
TEST(Implicit, LightMassStableFarPastTheExplicitLimitWithQuasiNewtonAndAitken) {
  st::OscParams p;
  st::set_param(p, "m1", 0.01);
  const double hj = *st::critical_macro_step(p, st::Scheme::Jacobi, 1, 0);
  const double hg = *st::critical_macro_step(p, st::Scheme::GaussSeidel, 1, 0);
  const std::vector<std::string> light = {"participants.mass1.parameters.mass=0.01"};
  for (const double H : {25 * hj, 20 * hg}) {
    const auto cfg = [&](const std::string& acc, int max_iterations, const std::string& at_max) {
      return harness::oscillator_config(join(join(implicit("gauss_seidel", acc, kTight, 0, max_iterations, at_max),
                                                   timing(H, 40)), light));
    };
    // The explicit run blows up: its amplitude grows past 1e3, or the participant refuses a
    // force that is no longer finite.
    std::string explicit_failure;
    try {
      const auto ex = run(harness::oscillator_config(join(join(explicit_gs(0), timing(H, 40)), light)));
      if (!(amplitude(ex.s.x1, 0.9, 1.0) < 1e3)) explicit_failure = "grew";
    } catch (const std::exception& e) {
      explicit_failure = e.what();
    }
    EXPECT_FALSE(explicit_failure.empty()) << "the explicit run should fail at H = " << H;
    // Plain iteration diverges: the step is refused naming the connection and its residual.
    std::string refused;
    try {
      run(cfg("{type: none}", 30, "stop"));
    } catch (const std::exception& e) {
      refused = e.what();
    }
    EXPECT_NE(refused.find("did not converge in 30 iterations: connection mass1.force has residual"), std::string::npos)
        << refused;
    const auto iqn = run(cfg(kIqn, 50, "stop"));
    const auto aitken = run(cfg(kAitken, 50, "stop"));
    std::printf("m1 = 0.01, H = %.4e s (%.1fx Jacobi, %.1fx Gauss-Seidel explicit limit): plain iteration: %s\n"
                "  IQN-ILS %.3f iterations/step, Aitken %.3f; |x1| %.3g -> %.3g\n",
                H, H / hj, H / hg, refused.substr(0, 120).c_str(), iqn.mean_iterations(), aitken.mean_iterations(),
                amplitude(iqn.s.x1, 0, 0.1), amplitude(iqn.s.x1, 0.9, 1));
    EXPECT_LE(iqn.mean_iterations(), 2.5);
    EXPECT_LE(aitken.mean_iterations(), 3.5);
    EXPECT_LT(amplitude(iqn.s.x1, 0.9, 1.0), 0.5 * amplitude(iqn.s.x1, 0, 0.1));
    EXPECT_LT(rate(iqn.s), 0);
    // Both accelerations reach the same converged solution.
    ASSERT_EQ(iqn.s.x1.size(), aitken.s.x1.size());
    for (std::size_t i = 0; i < iqn.s.x1.size(); ++i) ASSERT_NEAR(iqn.s.x1[i], aitken.s.x1[i], 1e-7) << i;
  }
}

// The converged scheme with linear interpolation of both the kinematics and the force: the
// error against the exact solution falls at second order in H (halving H divides it by ~4).
TEST(Implicit, ConvergedErrorFallsAtSecondOrderWithLinearInterpolation) {
  std::vector<double> errors;
  for (const double H : {4e-3, 2e-3, 1e-3}) {
    const auto cfg = harness::oscillator_config(join(implicit("gauss_seidel", kIqn, kTight, 1), timing(H, 1.0)));
    errors.push_back(harness::max_error(cfg, run(cfg).s));
  }
  std::printf("converged implicit (1,1): max |x1 - exact| = %.3e, %.3e, %.3e at H = 4, 2, 1 ms: orders %.2f, %.2f\n",
              errors[0], errors[1], errors[2], std::log2(errors[0] / errors[1]), std::log2(errors[1] / errors[2]));
  EXPECT_NEAR(std::log2(errors[0] / errors[1]), 2.0, 0.25);
  EXPECT_NEAR(std::log2(errors[1] / errors[2]), 2.0, 0.25);
}

// The limits of the implicit scheme that cosim_stability computes hold in the master: at 0.98
// of the computed critical step the run decays, at 1.02 it grows at the rate log(rho)/H.
// Converged (IQN-ILS to a tight tolerance) and with 2 and 3 plain iterations per step.
TEST(Implicit, LimitsEqualCosimStability) {
  for (const int iterations : {0, 2, 3}) {
    st::Predictors pr{1, 0, 0, 0, st::ForceUse::End};
    pr.iterations = iterations;
    st::ScanOptions wide;
    wide.h_max = 10;
    wide.points = 500;
    const auto hc = st::critical_macro_step({}, st::Scheme::GaussSeidel, pr, wide);
    ASSERT_TRUE(hc.has_value());
    for (const double factor : {0.98, 1.02}) {
      const double H = std::llround(factor * *hc * 1e9) * 1e-9;
      std::vector<std::string> o;
      if (iterations == 0) {
        o = implicit("gauss_seidel", kIqn, kTight, 0, 100, "stop");
      } else {
        o = implicit("gauss_seidel", "{type: none}", kTight, 0, iterations);
        o.push_back("coupling.min_iterations=" + std::to_string(iterations));
      }
      const auto r = run(harness::oscillator_config(join(o, timing(H, 40))));
      const double measured = rate(r.s);
      const double predicted = std::log(st::spectral_radius({}, st::Scheme::GaussSeidel, pr, H)) / H;
      std::printf("implicit %d iterations (0: converged): H_crit %.6e, H = %.2f H_crit: rate measured %+.4f /s, predicted %+.4f /s\n",
                  iterations, *hc, factor, measured, predicted);
      if (factor < 1) {
        EXPECT_LT(measured, 0);
        EXPECT_LT(measured, 0.95 * predicted);
      } else {
        EXPECT_GT(measured, 0);
        EXPECT_NEAR(measured, predicted, 0.05 * predicted);
      }
    }
  }
}

// preCICE's measures: absolute and relative stop where their definitions say; residual_relative
// measures against the step's first residual; `suffices` lets one measure decide; the residuals
// the record holds are below their limits.
TEST(Implicit, ConvergenceMeasuresStopWhereTheirDefinitionsSay) {
  const auto base = join(implicit("gauss_seidel", "{type: none}", "[]", 0), timing(2e-3, 0.2));
  const auto with = [&](const std::string& conv) {
    auto o = base;
    o.push_back("coupling.convergence=" + conv);
    return run(harness::oscillator_config(o));
  };
  const auto abs = with("[{connection: mass1.force, measure: absolute, limit: 1.0e-6}]");
  const auto rel = with("[{connection: mass1.force, measure: relative, limit: 1.0e-6}]");
  const auto rr = with("[{connection: mass1.force, measure: residual_relative, limit: 1.0e-3}]");
  const auto both = with("[{connection: mass1.force, measure: absolute, limit: 1.0e-12}, "
                         "{connection: mass2.x, measure: absolute, limit: 1.0e-3, suffices: true}]");
  for (std::size_t i = 1; i < abs.residuals.size(); ++i) {
    ASSERT_EQ(abs.residuals[i].size(), 1u);
    EXPECT_LE(abs.residuals[i][0], 1e-6) << i;
    EXPECT_LE(rel.residuals[i][0], 1e-6 * std::max(1e-300, std::abs(rel.s.force[i + 1])) * 1.0000001) << i;
  }
  // A tighter limit takes more iterations; `suffices` on a loose measure takes the fewest.
  const auto tight = with("[{connection: mass1.force, measure: absolute, limit: 1.0e-10}]");
  std::printf("mean iterations: absolute 1e-6 %.2f, 1e-10 %.2f, relative 1e-6 %.2f, residual_relative 1e-3 %.2f, suffices %.2f\n",
              abs.mean_iterations(), tight.mean_iterations(), rel.mean_iterations(), rr.mean_iterations(),
              both.mean_iterations());
  EXPECT_GT(tight.mean_iterations(), abs.mean_iterations());
  EXPECT_LT(both.mean_iterations(), tight.mean_iterations());
  EXPECT_GE(rr.mean_iterations(), 2.0);  // the first iteration's ratio is 1 by definition
}

// cosim_master and the participants as processes over LCM: every iteration after the first
// rolls the participants back over the bus; the record holds the iterations per step and the
// residual of each convergence measure (docs/output.md#implicit-coupling), and equals the
// in-process run bit for bit.
TEST(Implicit, OverLcmTheRecordHoldsIterationsAndResiduals) {
  const auto o = join(implicit("gauss_seidel", kIqn, "[{connection: mass1.force, measure: relative, limit: 1.0e-8}]", 0),
                      {"time.end=0.5", "time.macro_step=0.01", "participants.mass1.parameters.inner_step=1.0e-4",
                       "participants.mass2.parameters.inner_step=1.0e-4"});
  const std::string h5 = harness::temp_path(".h5");
  ASSERT_EQ(harness::run_master(o, h5, 300), 0) << harness::read_text(h5 + ".log");
  const auto iterations = harness::read_dataset(h5, "timing/iterations");
  const auto residual = harness::read_dataset(h5, "coupling/residual");
  const auto force = harness::read_dataset(h5, "participants/mass2/outputs/force");
  ASSERT_EQ(iterations.size(), 51u);
  ASSERT_EQ(residual.size(), 51u);
  EXPECT_TRUE(std::isnan(residual[0]));  // row 0: t_start
  auto in_process = o;
  in_process.insert(in_process.end(), {"output.file=", "output.csv="});
  const auto r = run(harness::oscillator_config(in_process));
  for (std::size_t i = 1; i < iterations.size(); ++i) {
    EXPECT_GE(iterations[i], 2) << i;
    EXPECT_EQ(iterations[i], r.iterations[i - 1]) << i;
    EXPECT_LE(residual[i], 1e-8 * std::abs(force[i])) << i;
    EXPECT_EQ(residual[i], r.residuals[i - 1][0]) << i;
    EXPECT_EQ(force[i], r.s.force[i]) << i;
  }
}
