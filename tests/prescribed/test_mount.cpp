// The prescribed participant's mounted tool (docs/prescribed.md, `mount`): a mass on a spring
// and damper to its trajectory, pushed by the received force. Checked against the closed form
// of the damped oscillator's step response, repeated steps and checkpoints bit for bit, and
// bad mounts refused naming the key.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "cosim/quantities.hpp"
#include "cosim/yaml_config.hpp"
#include "prescribed_adapter.hpp"

namespace {

constexpr double kMass = 2.0, kStiffness = 800.0, kDamping = 8.0;  // omega 20 rad/s, zeta 0.1

YAML::Node parameters(const std::string& inner_step = "1.0e-4", const std::string& mount = "") {
  const std::string m = mount.empty() ? "{mass: 2.0, stiffness: 800.0, damping: 8.0}" : mount;
  std::string text = "tools:\n  - name: blade\n    keyframes:\n"
                     "      - {time: 0.0, position: [1.0, 2.0, 3.0], orientation: [1, 0, 0, 0]}\n"
                     "    mount: " + m + "\n";
  if (!inner_step.empty()) text += "inner_step: " + inner_step + "\n";
  return YAML::Load(text);
}

cosim::RunInfo run_info() {
  cosim::RunInfo r;
  r.participant = "tool";
  r.t_end = cosim::time_point_ns(10'000'000'000);
  r.macro_step = cosim::Duration(1'000'000);
  return r;
}

// One macro step [k H, (k+1) H] with a constant force (fx, 0, 0) on the blade.
cosim::StepResult step(prescribed::PrescribedAdapter& a, long long k, long long H_ns, double fx) {
  cosim::Polynomials in;
  in["blade_wrench"] = cosim::InputPolynomial::constant(
      cosim::SignalKind::Wrench, cosim::Wrench{{fx, 0, 0}, {}, {}}.to_value());
  const cosim::StepInputs s(cosim::time_point_ns(k * H_ns), cosim::time_point_ns((k + 1) * H_ns), in);
  return a.step(s, false);
}

cosim::Kinematics blade(const cosim::StepResult& r) {
  return cosim::Kinematics::from_value(r.outputs.at("blade").value);
}

std::string refusal(const YAML::Node& p) {
  prescribed::PrescribedAdapter a(YAML::Node(), "");
  try {
    a.configure(p, run_info());
  } catch (const cosim::config::ConfigError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Mount, StepResponseEqualsTheDampedOscillatorsClosedForm) {
  // Driver at rest at (1, 2, 3); from t = 0 a constant force F pushes the blade along x:
  // x(t) = x0 + F/k (1 - exp(-zeta w t) (cos(wd t) + zeta w / wd sin(wd t))).
  prescribed::PrescribedAdapter a(YAML::Node(), "");
  a.configure(parameters(), run_info());
  const double F = 40.0, w = std::sqrt(kStiffness / kMass), zeta = kDamping / (2 * std::sqrt(kStiffness * kMass));
  const double wd = w * std::sqrt(1 - zeta * zeta);
  const long long H = 1'000'000;  // 1 ms: 10 inner steps of 0.1 ms
  double worst = 0, worst_v = 0;
  for (long long k = 0; k < 1000; ++k) {
    const auto b = blade(step(a, k, H, F));
    const double t = static_cast<double>(k + 1) * 1e-3;
    const double e = std::exp(-zeta * w * t);
    const double x = 1.0 + F / kStiffness * (1 - e * (std::cos(wd * t) + zeta * w / wd * std::sin(wd * t)));
    const double v = F / kStiffness * e * (w * w / wd) * std::sin(wd * t);
    worst = std::max(worst, std::abs(b.position[0] - x));
    worst_v = std::max(worst_v, std::abs(b.velocity[0] - v));
    ASSERT_EQ(b.position[1], 2.0);
    ASSERT_EQ(b.position[2], 3.0);
  }
  // The amplitude is F/k = 0.05 m; RK4 at h w = 2e-3 is exact to far below 1e-9 of it.
  std::printf("mount: largest |x - closed form| %.3e m, |v - closed form| %.3e m/s over 1 s\n", worst, worst_v);
  EXPECT_LT(worst, 1e-10);
  EXPECT_LT(worst_v, 1e-9);
}

TEST(Mount, GravitySagsTheBladeAtRestAndTheEnergyIsReported) {
  prescribed::PrescribedAdapter a(YAML::Node(), "");
  a.configure(parameters("1.0e-4", "{mass: 2.0, stiffness: 800.0, damping: 8.0, gravity: [0, 0, -9.81]}"),
              run_info());
  cosim::StepResult initial;
  initial.outputs = a.initial_outputs();
  const auto r0 = blade(initial);
  EXPECT_DOUBLE_EQ(r0.position[2], 3.0 - 2.0 * 9.81 / 800.0);  // at rest on the spring
  const auto r = step(a, 0, 1'000'000, 0.0);
  EXPECT_NEAR(blade(r).position[2], 3.0 - 2.0 * 9.81 / 800.0, 1e-15);  // and stays there
  ASSERT_EQ(r.diagnostics.size(), 1u);
  EXPECT_EQ(r.diagnostics[0].first, "mount_energy");
  const double sag = 2.0 * 9.81 / 800.0;
  EXPECT_NEAR(r.diagnostics[0].second, 0.5 * 800.0 * sag * sag, 1e-12);
}

TEST(Mount, RepeatedStepsAndCheckpointsAreBitIdentical) {
  const std::string dir = ::testing::TempDir();
  prescribed::PrescribedAdapter a(YAML::Node(), "");
  a.configure(parameters(), run_info());
  for (long long k = 0; k < 5; ++k) step(a, k, 1'000'000, 10.0 * static_cast<double>(k));
  a.save_snapshot();
  const auto first = blade(step(a, 5, 1'000'000, 50.0));
  a.restore_snapshot();
  step(a, 5, 1'000'000, -300.0);  // another attempt at the step
  a.restore_snapshot();
  const auto again = blade(step(a, 5, 1'000'000, 50.0));
  EXPECT_EQ(first.to_value(), again.to_value());
  // A checkpoint after step 5, loaded into a fresh adapter: step 6 the same bits.
  const std::string path = dir + "/mount_checkpoint.txt";
  a.save_checkpoint(path);
  const auto next = blade(step(a, 6, 1'000'000, 70.0));
  prescribed::PrescribedAdapter b(YAML::Node(), "");
  auto info = run_info();
  info.resume_steps_done = 6;
  b.configure(parameters(), info);
  b.load_checkpoint(path);
  EXPECT_EQ(blade(step(b, 6, 1'000'000, 70.0)).to_value(), next.to_value());
  // A version-1 checkpoint (no mount states) is refused for a mounted tool.
  {
    FILE* f = std::fopen(path.c_str(), "w");
    std::fputs("prescribed_checkpoint 1\nrecord_bytes 0\n", f);
    std::fclose(f);
  }
  EXPECT_THROW(b.load_checkpoint(path), std::runtime_error);
}

TEST(Mount, BadMountsAreRefusedNamingTheKey) {
  EXPECT_NE(refusal(parameters("")).find("inner_step: tool 'blade' has a mount"), std::string::npos)
      << refusal(parameters(""));
  // w = 20 rad/s: an inner step above 0.2 / 20 = 0.01 s is refused, naming the largest.
  const std::string coarse = refusal(parameters("0.02"));
  EXPECT_NE(coarse.find("at most 0.01 s"), std::string::npos) << coarse;
  EXPECT_EQ(refusal(parameters("0.005")), "");
  EXPECT_NE(refusal(parameters("1e-4", "{mass: 0, stiffness: 800}")).find("mass"), std::string::npos);
  EXPECT_NE(refusal(parameters("1e-4", "{mass: 1, stiffness: -5}")).find("stiffness"), std::string::npos);
  EXPECT_NE(refusal(parameters("1e-4", "{mass: 1, stiffness: 5, damping: -1}")).find("damping: must be >= 0"),
            std::string::npos);
  EXPECT_NE(refusal(parameters("1e-4", "{mass: 1, stiffness: 5, spring: 3}")).find("spring"), std::string::npos);
  EXPECT_NE(refusal(parameters("1e-4", "{mass: 1, stiffness: 5, gravity: [0, 0]}")).find("gravity"),
            std::string::npos);
  EXPECT_NE(refusal(parameters("1e-4", "3.0")).find("mount: give a map"), std::string::npos);
}
