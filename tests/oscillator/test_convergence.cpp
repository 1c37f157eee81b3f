// Convergence order of the co-simulation against the exact monolithic solution of the
// dual-mass oscillator: min(k_q, k_F) + 1 (facts.md), Jacobi and Gauss-Seidel.
#include <cmath>

#include "harness.hpp"

namespace {

struct Case {
  int kq, kf;
  double order;
};

// use: the force connection's (mass2.force -> mass1.force) `use`, end or average.
std::vector<double> errors(const std::string& scheme, int kq, int kf, const std::string& use = "end") {
  std::vector<double> e;
  for (double H : {1e-3, 5e-4, 2.5e-4, 1.25e-4}) {
    const auto config = harness::oscillator_config(
        {"scheme=" + scheme, "order=[mass2, mass1]", "time.macro_step=" + std::to_string(H),
         "predictors.kinematics.order=" + std::to_string(kq),
         "predictors.force.order=" + std::to_string(kf), "connections.2.use=" + use,
         "output.file=", "output.csv="});
    e.push_back(harness::max_error(config, harness::run_in_process(config)));
  }
  return e;
}

double observed_order(const std::vector<double>& e) {
  // least-squares slope of log2(error) against log2(1/H) over the halvings
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const int n = static_cast<int>(e.size());
  for (int i = 0; i < n; ++i) {
    sx += i, sy += -std::log2(e[i]), sxx += i * i, sxy += i * -std::log2(e[i]);
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

}  // namespace

class Convergence : public ::testing::TestWithParam<Case> {};

TEST_P(Convergence, JacobiOrderMatchesTheory) {
  const auto c = GetParam();
  const auto e = errors("jacobi", c.kq, c.kf);
  const double order = observed_order(e);
  std::printf("jacobi (%d,%d): errors %.3e %.3e %.3e %.3e -> order %.3f\n", c.kq, c.kf, e[0], e[1], e[2], e[3], order);
  EXPECT_NEAR(order, c.order, 0.1);
  // every halving, not just the fit
  for (std::size_t i = 0; i + 1 < e.size(); ++i) EXPECT_NEAR(std::log2(e[i] / e[i + 1]), c.order, 0.25);
}

TEST_P(Convergence, GaussSeidelIsAtLeastAsAccurateAsJacobi) {
  const auto c = GetParam();
  const auto j = errors("jacobi", c.kq, c.kf);
  const auto g = errors("gauss_seidel", c.kq, c.kf);
  std::printf("gauss_seidel (%d,%d): errors %.3e %.3e %.3e %.3e -> order %.3f\n", c.kq, c.kf, g[0], g[1], g[2], g[3], observed_order(g));
  for (std::size_t i = 0; i < j.size(); ++i) EXPECT_LE(g[i], j[i] * 1.0001) << "macro step index " << i;
  EXPECT_GE(observed_order(g), c.order - 0.1);
}

INSTANTIATE_TEST_SUITE_P(Orders, Convergence,
                         ::testing::Values(Case{0, 0, 1.0}, Case{1, 0, 1.0}, Case{1, 1, 2.0}, Case{2, 2, 3.0}),
                         [](const auto& info) {
                           return "kq" + std::to_string(info.param.kq) + "_kf" + std::to_string(info.param.kf);
                         });

// use: average on the force: the received interval means are fitted by histopolation, which
// reproduces polynomials of the configured order exactly, so the force error over a step is
// O(H^(kf+1)) as with end samples and the order stays min(kq, kf) + 1 (docs/stability.md,
// "Interval averages"). The start-up keeps it: step 0's constant has the exact mean.
class AverageConvergence : public ::testing::TestWithParam<Case> {};

TEST_P(AverageConvergence, OrderMatchesTheory) {
  const auto c = GetParam();
  for (const std::string scheme : {"jacobi", "gauss_seidel"}) {
    const auto e = errors(scheme, c.kq, c.kf, "average");
    const double order = observed_order(e);
    std::printf("%s (%d,%d) use average: errors %.3e %.3e %.3e %.3e -> order %.3f (expected %.0f)\n",
                scheme.c_str(), c.kq, c.kf, e[0], e[1], e[2], e[3], order, c.order);
    EXPECT_NEAR(order, c.order, 0.25) << scheme;
    for (std::size_t i = 0; i + 1 < e.size(); ++i)
      EXPECT_NEAR(std::log2(e[i] / e[i + 1]), c.order, 0.25) << scheme << " halving " << i;
  }
}

INSTANTIATE_TEST_SUITE_P(Orders, AverageConvergence,
                         ::testing::Values(Case{0, 0, 1.0}, Case{1, 1, 2.0}, Case{2, 2, 3.0}),
                         [](const auto& info) {
                           return "kq" + std::to_string(info.param.kq) + "_kf" + std::to_string(info.param.kf);
                         });
