// Where the method fails: Jacobi with constant predictors (0,0) on the dual-mass oscillator
// grows without bound at macro step 1e-3 s and decays at 5e-4 s (facts.md), in one process
// and as three processes over LCM.
#include <cmath>

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

TEST(Instability, ProcessesOverLcmAgree) {
  const std::string a = harness::temp_path("_1ms.h5"), b = harness::temp_path("_500us.h5");
  ASSERT_EQ(harness::run_master(jacobi00(1e-3), a, 300), 0) << harness::read_text(a + ".log");
  ASSERT_EQ(harness::run_master(jacobi00(5e-4), b, 300), 0) << harness::read_text(b + ".log");
  EXPECT_GT(growth(harness::read_dataset(a, "participants/mass2/outputs/force")), 2.0);
  EXPECT_LT(growth(harness::read_dataset(b, "participants/mass2/outputs/force")), 0.5);
}
