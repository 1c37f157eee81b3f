// Where the method fails: Jacobi with constant predictors (0,0) on the dual-mass oscillator
// grows without bound at macro step 1e-3 s and decays at 5e-4 s (facts.md), in one process
// and as three processes over LCM.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <utility>

#include "stability.hpp"

#include "harness.hpp"

namespace {

// Growth of the coupling force amplitude from the fifth to the last tenth of the run, once the
// physical modes have died out and the scheme's own dominant mode is left.
double growth(const std::vector<double>& force) {
  const std::size_t n = force.size(), tenth = n / 10;
  double middle = 0, last = 0;
  for (std::size_t i = 4 * tenth; i < 5 * tenth; ++i) middle = std::max(middle, std::abs(force[i]));
  for (std::size_t i = n - tenth; i < n; ++i) last = std::max(last, std::abs(force[i]));
  return last / middle;
}

std::vector<std::string> jacobi00(double H) {
  // The halves integrate exactly, so a coarse inner step changes nothing but the cost.
  return {"scheme=jacobi", "predictors.kinematics.order=0", "predictors.force.order=0",
          "time.end=100", "time.macro_step=" + std::to_string(H),
          "participants.mass1.parameters.inner_step=1e-4", "participants.mass2.parameters.inner_step=1e-4",
          "output.csv="};
}

}  // namespace

TEST(Instability, Jacobi00GrowsAt1msAndDecaysAt500usInProcess) {
  auto with_no_file = [](std::vector<std::string> o) { o.push_back("output.file="); return o; };
  const double g_unstable = growth(harness::run_in_process(harness::oscillator_config(with_no_file(jacobi00(1e-3)))).force);
  const double g_stable = growth(harness::run_in_process(harness::oscillator_config(with_no_file(jacobi00(5e-4)))).force);
  std::printf("force amplitude growth over 100 s: H = 1e-3: %.3g, H = 5e-4: %.3g\n", g_unstable, g_stable);
  // spectral radius 1.000025 per step -> exp(0.025 * 50) = 3.5 over the last 50 s; 0.999981 decays
  EXPECT_GT(g_unstable, 2.0);
  EXPECT_LT(g_stable, 0.5);
}

// As three processes over LCM: the unstable run (100 s, 100,000 macro steps, past any 16-bit
// step counter) grows, and both runs are the in-process runs bit for bit (the stable one over
// its first 10 s, 20,000 steps: the whole 100 s over LCM took 200,000 round trips, two thirds of
// the test's time, for a decay the in-process run above shows from the same numbers).
TEST(Instability, ProcessesOverLcmAgree) {
  auto with_no_file = [](std::vector<std::string> o) { o.push_back("output.file="); return o; };
  auto until = [](std::vector<std::string> o, const std::string& end) { o.push_back("time.end=" + end); return o; };
  auto identical = [](const std::vector<double>& a, const std::vector<double>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
  };
  const std::string a = harness::temp_path("_1ms.h5"), b = harness::temp_path("_500us.h5");
  ASSERT_EQ(harness::run_master(jacobi00(1e-3), a, 300), 0) << harness::read_text(a + ".log");
  ASSERT_EQ(harness::run_master(until(jacobi00(5e-4), "10"), b, 300), 0) << harness::read_text(b + ".log");
  const auto force_a = harness::read_dataset(a, "participants/mass2/outputs/force");
  ASSERT_EQ(force_a.size(), 100'001u);
  EXPECT_GT(growth(force_a), 2.0);
  const auto in_a = harness::run_in_process(harness::oscillator_config(with_no_file(jacobi00(1e-3))));
  const auto in_b = harness::run_in_process(harness::oscillator_config(with_no_file(until(jacobi00(5e-4), "10"))));
  ASSERT_EQ(harness::read_dataset(b, "participants/mass2/outputs/force").size(), 20'001u);
  for (const auto& [h5, s] : {std::pair{a, in_a}, std::pair{b, in_b}}) {
    EXPECT_TRUE(identical(harness::read_dataset(h5, "participants/mass1/outputs/x"), s.x1)) << h5;
    EXPECT_TRUE(identical(harness::read_dataset(h5, "participants/mass1/outputs/v"), s.v1)) << h5;
    EXPECT_TRUE(identical(harness::read_dataset(h5, "participants/mass2/outputs/force"), s.force)) << h5;
  }
}

// The processes agree with the linear theory of cosim_stability: for each scheme and predictor
// pair, a run at 0.98 of the computed critical macro step decays and a run at 1.02 grows, at the
// rate log(rho)/H that the spectral radius of the one-step map predicts.
namespace {

struct Case {
  const char* scheme;
  int kq, kf;
};

double predicted_rate(cosim::stability::Scheme scheme, const Case& c, double H) {
  return std::log(cosim::stability::spectral_radius({}, scheme, c.kq, c.kf, 0, 0, H)) / H;
}

// Macro step rounded to whole nanoseconds; the halves integrate exactly, so one inner step per
// macro step changes nothing but the cost. About 100 s of simulated time.
std::vector<std::string> near_critical(const Case& c, double H) {
  const long long ns = std::llround(H * 1e9);
  const long long steps = (100'000'000'000LL + ns - 1) / ns;
  char h[64], end[64];
  std::snprintf(h, sizeof h, "%.9f", ns * 1e-9);
  std::snprintf(end, sizeof end, "%.9f", steps * ns * 1e-9);
  return {std::string("scheme=") + c.scheme,
          "order=[mass1, mass2]",
          "predictors.kinematics.order=" + std::to_string(c.kq),
          "predictors.force.order=" + std::to_string(c.kf),
          std::string("time.end=") + end,
          std::string("time.macro_step=") + h,
          std::string("participants.mass1.parameters.inner_step=") + h,
          std::string("participants.mass2.parameters.inner_step=") + h,
          "output.csv="};
}

// Measured rate: log of the amplitude ratio between the fifth and the last tenth of the run,
// over the time between them (the windows' maxima are about 0.5 T apart).
double measured_rate(const std::vector<double>& force, double t_end) {
  return std::log(growth(force)) / (0.5 * t_end);
}

double rounded(double H) { return std::llround(H * 1e9) * 1e-9; }

}  // namespace

TEST(Instability, RunsAgreeWithTheComputedCriticalMacroStep) {
  using cosim::stability::Scheme;
  // The stability tool's Gauss-Seidel steps mass1 first (near_critical sets that order).
  const Case cases[] = {{"jacobi", 1, 0}, {"jacobi", 1, 1}, {"jacobi", 2, 2},
                        {"gauss_seidel", 1, 0}, {"gauss_seidel", 1, 1}};
  for (const Case& c : cases) {
    const Scheme scheme = std::string(c.scheme) == "jacobi" ? Scheme::Jacobi : Scheme::GaussSeidel;
    const auto critical = cosim::stability::critical_macro_step({}, scheme, c.kq, c.kf);
    ASSERT_TRUE(critical.has_value()) << c.scheme << " (" << c.kq << "," << c.kf << ")";
    for (const double factor : {0.98, 1.02}) {
      const double H = rounded(factor * *critical);
      auto overrides = near_critical(c, H);
      overrides.push_back("output.file=");
      const auto config = harness::oscillator_config(overrides);
      const harness::Series s = harness::run_in_process(config);
      const double measured = measured_rate(s.force, s.t.back());
      const double predicted = predicted_rate(scheme, c, H);
      std::printf("%-12s (%d,%d) H_crit %.6e  H = %.4f H_crit: rate measured %+.4f /s, predicted %+.4f /s\n",
                  c.scheme, c.kq, c.kf, *critical, factor, measured, predicted);
      if (factor < 1) {
        // rho bounds every mode; below the limit the slowest one may be the physical in-phase
        // mode (rate -0.1 /s), which the coupling force hardly contains, so it decays faster.
        EXPECT_LT(measured, 0) << c.scheme << " must decay below the limit";
        EXPECT_LT(measured, 0.95 * predicted) << c.scheme << " decays slower than rho allows";
      } else {
        // Above the limit the growing mode takes over and its rate is rho's.
        EXPECT_GT(measured, 0) << c.scheme << " must grow above the limit";
        EXPECT_NEAR(measured, predicted, 0.05 * predicted) << c.scheme << " H = " << H;
      }
    }
  }
}

TEST(Instability, ProcessesOverLcmAgreeWithTheComputedCriticalMacroStep) {
  using cosim::stability::Scheme;
  const Case c{"jacobi", 1, 0};
  const double critical = *cosim::stability::critical_macro_step({}, Scheme::Jacobi, 1, 0);
  for (const double factor : {0.98, 1.02}) {
    const double H = rounded(factor * critical);
    const std::string h5 = harness::temp_path(factor < 1 ? "_below.h5" : "_above.h5");
    ASSERT_EQ(harness::run_master(near_critical(c, H), h5, 300), 0) << harness::read_text(h5 + ".log");
    const auto force = harness::read_dataset(h5, "participants/mass2/outputs/force");
    const auto t = harness::read_dataset(h5, "time");
    ASSERT_FALSE(t.empty());
    const double measured = measured_rate(force, t.back());
    const double predicted = predicted_rate(Scheme::Jacobi, c, H);
    std::printf("over LCM: jacobi (1,0) H = %.4f H_crit: rate measured %+.4f /s, predicted %+.4f /s\n",
                factor, measured, predicted);
    if (factor < 1) EXPECT_LT(measured, 0.95 * predicted);
    else EXPECT_NEAR(measured, predicted, 0.05 * predicted);
  }
}

// The same for the averaged force connection (use: average on mass2.force -> mass1.force): the
// critical macro step and rate of cosim_stability's ForceUse::Average map against the running
// master, whose oscillator returns the exact interval mean of its coupling force.
TEST(Instability, AveragedForceRunsAgreeWithTheComputedCriticalMacroStep) {
  using cosim::stability::ForceUse;
  using cosim::stability::Predictors;
  using cosim::stability::Scheme;
  const Case cases[] = {{"jacobi", 1, 0}, {"jacobi", 1, 1}, {"gauss_seidel", 1, 0}};
  for (const Case& c : cases) {
    const Scheme scheme = std::string(c.scheme) == "jacobi" ? Scheme::Jacobi : Scheme::GaussSeidel;
    const Predictors pr{c.kq, c.kf, 0, 0, ForceUse::Average};
    const auto critical = cosim::stability::critical_macro_step({}, scheme, pr);
    ASSERT_TRUE(critical.has_value()) << c.scheme << " (" << c.kq << "," << c.kf << ")";
    for (const double factor : {0.98, 1.02}) {
      const double H = rounded(factor * *critical);
      auto overrides = near_critical(c, H);
      overrides.push_back("connections.2.use=average");
      overrides.push_back("output.file=");
      const harness::Series s = harness::run_in_process(harness::oscillator_config(overrides));
      const double measured = measured_rate(s.force, s.t.back());
      const double predicted = std::log(cosim::stability::spectral_radius({}, scheme, pr, H)) / H;
      std::printf("%-12s (%d,%d) use average H_crit %.6e  H = %.4f H_crit: rate measured %+.4f /s, predicted %+.4f /s\n",
                  c.scheme, c.kq, c.kf, *critical, factor, measured, predicted);
      if (factor < 1) {
        EXPECT_LT(measured, 0) << c.scheme << " must decay below the limit";
        EXPECT_LT(measured, 0.95 * predicted) << c.scheme << " decays slower than rho allows";
      } else {
        EXPECT_GT(measured, 0) << c.scheme << " must grow above the limit";
        EXPECT_NEAR(measured, predicted, 0.05 * predicted) << c.scheme << " H = " << H;
      }
    }
  }
}
