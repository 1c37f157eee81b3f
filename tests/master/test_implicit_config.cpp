// Implicit coupling's keys (docs/config.md#implicit-coupling): parsed, bad settings refused with
// messages that name the key and the fix; a participant that cannot repeat a step refused by
// name before the run; the accelerations on linear fixed-point problems with known answers.
#include <gtest/gtest.h>

#include <cmath>

#include "acceleration.hpp"
#include "config.hpp"
#include "coupling_algorithm.hpp"

namespace {

const char* kBase = R"(
time: {end: 1.0, macro_step: 1.0e-3}
participants: {a: null, b: {}}
connections: [{from: a.x, to: b.x}, {from: b.f, to: a.f}]
)";

master::Config parse(const std::vector<std::string>& sets) {
  YAML::Node root = YAML::Load(kBase);
  for (const auto& s : sets) cosim::config::apply_override(root, s);
  return master::parse_config(root, kBase);
}

std::string error(const std::vector<std::string>& sets) {
  try {
    parse(sets);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

const std::string kConv = "coupling.convergence=[{connection: a.f, measure: relative, limit: 1.0e-6}]";

}  // namespace

TEST(master_ImplicitConfig, ParsesEveryKey) {
  const auto c = parse({"coupling.type=implicit", "coupling.min_iterations=2", "coupling.max_iterations=30",
                        "coupling.at_max_iterations=stop",
                        "coupling.convergence=[{connection: a.f, measure: absolute_or_relative, absolute: 1.0e-9, "
                        "relative: 1.0e-5, suffices: true}, {connection: b.x, measure: residual_relative, limit: 0.01}]",
                        "coupling.acceleration={type: iqn_ils, relaxation: 0.3, reuse: 4, max_columns: 20, filter: 0.001}"});
  EXPECT_EQ(c.coupling.type, master::CouplingType::Implicit);
  EXPECT_EQ(c.coupling.min_iterations, 2);
  EXPECT_EQ(c.coupling.max_iterations, 30);
  EXPECT_TRUE(c.coupling.stop_at_max);
  ASSERT_EQ(c.coupling.convergence.size(), 2u);
  EXPECT_EQ(c.coupling.convergence[0].connection, 1u);
  EXPECT_EQ(c.coupling.convergence[0].measure, master::Measure::AbsoluteOrRelative);
  EXPECT_EQ(c.coupling.convergence[0].limit, 1e-9);
  EXPECT_EQ(c.coupling.convergence[0].relative_limit, 1e-5);
  EXPECT_TRUE(c.coupling.convergence[0].suffices);
  EXPECT_EQ(c.coupling.convergence[1].connection, 0u);
  EXPECT_EQ(c.coupling.convergence[1].measure, master::Measure::ResidualRelative);
  EXPECT_EQ(c.coupling.acceleration.type, master::AccelerationType::IqnIls);
  EXPECT_EQ(c.coupling.acceleration.relaxation, 0.3);
  EXPECT_EQ(c.coupling.acceleration.reuse, 4);
  EXPECT_EQ(c.coupling.acceleration.max_columns, 20);
  EXPECT_EQ(c.coupling.acceleration.filter, 0.001);
  // The default: explicit, and make_algorithm gives the fixed step.
  EXPECT_EQ(parse({}).coupling.type, master::CouplingType::Explicit);
  EXPECT_NE(master::make_algorithm(parse({}))->name().find("fixed step"), std::string::npos);
  auto alg = master::make_algorithm(c);
  alg->setup(c);
  EXPECT_EQ(alg->name(), "implicit (Jacobi, iqn_ils)");
}

TEST(master_ImplicitConfig, BadSettingsAreRefusedNamingTheKeyAndTheFix) {
  struct Case {
    std::vector<std::string> sets;
    std::vector<std::string> said;
  };
  const std::vector<Case> cases = {
      {{"coupling.type=iterative"}, {"coupling.type", "explicit", "implicit"}},
      {{"coupling.type=implicit"}, {"coupling.convergence: missing", "measure: relative"}},
      {{"coupling.max_iterations=5"}, {"coupling.max_iterations", "only for coupling.type: implicit"}},
      {{"coupling.type=implicit", kConv, "coupling.max_iterations=0"}, {"coupling.max_iterations", "1 to 1000"}},
      {{"coupling.type=implicit", kConv, "coupling.min_iterations=9", "coupling.max_iterations=3"},
       {"coupling.min_iterations: 9", "coupling.max_iterations = 3"}},
      {{"coupling.type=implicit", kConv, "coupling.at_max_iterations=ignore"}, {"at_max_iterations", "accept", "stop"}},
      {{"coupling.type=implicit", "coupling.convergence=[{connection: a.y, measure: relative, limit: 1.0e-6}]"},
       {"coupling.convergence.0.connection", "'a.y'", "b.x, a.f"}},
      {{"coupling.type=implicit", "coupling.convergence=[{connection: a.f, measure: relativ, limit: 1.0e-6}]"},
       {"coupling.convergence.0", "absolute_or_relative"}},
      {{"coupling.type=implicit", "coupling.convergence=[{connection: a.f, measure: relative, limit: -1}]"},
       {"coupling.convergence.0.limit", "> 0"}},
      {{"coupling.type=implicit", "coupling.convergence=[{connection: a.f, measure: absolute_or_relative, limit: 1}]"},
       {"coupling.convergence.0", "limit"}},
      {{"coupling.type=implicit", kConv, "coupling.acceleration={type: anderson}"}, {"coupling.acceleration", "iqn_ils", "aitken"}},
      {{"coupling.type=implicit", kConv, "coupling.acceleration={type: constant, relaxation: 1.5}"},
       {"coupling.acceleration.relaxation: 1.5", "<= 1"}},
      {{"coupling.type=implicit", kConv, "coupling.acceleration={type: aitken, reuse: 3}"}, {"coupling.acceleration", "reuse"}},
      {{"coupling.type=implicit", kConv, "coupling.acceleration={type: iqn_ils, reuse: -1}"}, {"coupling.acceleration.reuse", "0 to 100"}},
      {{"coupling.type=implicit", kConv, "coupling.acceleration={type: iqn_ils, filter: 1}"}, {"coupling.acceleration.filter", "0 <= filter < 1"}},
      {{"power=[{name: p, force: b.f, velocity: a.x}]", "coupling.adaptive={min_step: 1.0e-4}"}, {"coupling.adaptive", "max_step"}},
      {{"power=[{name: p, force: b.f, velocity: a.x}]", "coupling.adaptive={min_step: 2.0e-3, max_step: 1.0e-2}"},
       {"coupling.adaptive: min_step 0.002 s <= time.macro_step 0.001 s"}},
      {{"coupling.adaptive={min_step: 1.0e-4, max_step: 1.0e-2}"}, {"coupling.adaptive", "`power` lists none"}},
      {{"power=[{name: p, force: b.f, velocity: a.x}]", "coupling.adaptive={min_step: 1.0e-4, max_step: 1.0e-2, safety: 1.5}"},
       {"coupling.adaptive.safety: 1.5", "<= 1"}},
      {{"power=[{name: p, force: b.f, velocity: a.x}]", "coupling.adaptive={min_step: 1.0e-4, max_step: 1.0e-2, gain: 1}"},
       {"coupling.adaptive", "gain"}},
  };
  for (const auto& c : cases) {
    const std::string e = error(c.sets);
    ASSERT_FALSE(e.empty()) << c.sets.back() << " was accepted";
    for (const auto& s : c.said) EXPECT_NE(e.find(s), std::string::npos) << "'" << e << "' lacks '" << s << "'";
  }
}

TEST(master_ImplicitConfig, AdaptiveStepParsesAndWrapsEitherAlgorithm) {
  const std::vector<std::string> sets = {"power=[{name: p, force: b.f, velocity: a.x}]",
      "coupling.adaptive={min_step: 1.0e-4, max_step: 1.0e-2, abs_tolerance: 1.0e-5, rel_tolerance: 0.01, "
      "p_gain: 0.3, i_gain: 0.2, safety: 0.9, min_change: 0.5, max_change: 2}"};
  const auto c = parse(sets);
  EXPECT_TRUE(c.coupling.adaptive.enabled);
  EXPECT_EQ(c.coupling.adaptive.min_step, cosim::Duration(100000));
  EXPECT_EQ(c.coupling.adaptive.max_step, cosim::Duration(10000000));
  EXPECT_EQ(c.coupling.adaptive.abs_tolerance, 1e-5);
  EXPECT_EQ(c.coupling.adaptive.rel_tolerance, 0.01);
  EXPECT_EQ(c.coupling.adaptive.p_gain, 0.3);
  EXPECT_EQ(c.coupling.adaptive.i_gain, 0.2);
  EXPECT_EQ(c.coupling.adaptive.safety, 0.9);
  EXPECT_EQ(c.coupling.adaptive.min_change, 0.5);
  EXPECT_EQ(c.coupling.adaptive.max_change, 2);
  auto a = master::make_algorithm(c);
  a->setup(c);
  EXPECT_EQ(a->name(), "fixed step (Jacobi), adaptive step");
  auto with_implicit = sets;
  with_implicit.insert(with_implicit.end(), {"coupling.type=implicit", kConv});
  const auto ci = parse(with_implicit);
  auto b = master::make_algorithm(ci);
  b->setup(ci);
  EXPECT_EQ(b->name(), "implicit (Jacobi, none), adaptive step");
  // No multiple of the inner steps between the bounds: refused after the handshake.
  std::map<std::string, cosim::ParticipantInfo> infos;
  infos["a"].inner_step = cosim::Duration(3000000);
  infos["b"].inner_step = cosim::Duration(7000000);  // lcm 21 ms > max_step 10 ms
  try {
    a->initialize({&infos, 0});
    FAIL() << "bounds without a multiple of the inner steps were accepted";
  } catch (const cosim::config::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("21000000 ns"), std::string::npos) << e.what();
  }
}

TEST(master_ImplicitConfig, AParticipantThatCannotRepeatAStepIsRefusedByName) {
  const auto c = parse({"coupling.type=implicit", kConv});
  master::ImplicitAlgorithm alg;
  alg.setup(c);
  std::map<std::string, cosim::ParticipantInfo> infos;
  infos["a"].can_repeat = true;
  infos["b"].can_repeat = false;
  infos["b"].repeat_note = "an FMU without state";
  try {
    alg.initialize({&infos, 1});
    FAIL() << "a participant that cannot repeat a step was accepted";
  } catch (const cosim::config::ConfigError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("participant 'b' cannot repeat a step (an FMU without state)"), std::string::npos) << m;
    EXPECT_NE(m.find("coupling.type: explicit"), std::string::npos) << m;
  }
  infos["b"].can_repeat = true;
  EXPECT_NO_THROW(alg.initialize({&infos, 1}));
}

TEST(master_ImplicitConfig, ImplicitAndAdaptiveRunsTakeCheckpoints) {
  EXPECT_EQ(parse({"coupling.type=implicit", kConv, "checkpoints.every=0.01"}).checkpoints.every, cosim::Duration(10000000));
  EXPECT_EQ(parse({"power=[{name: p, force: b.f, velocity: a.x}]", "checkpoints.every=0.01",
                   "coupling.adaptive={min_step: 1.0e-4, max_step: 1.0e-2, reject_above: 2}"})
                .checkpoints.every,
            cosim::Duration(10000000));
}

TEST(master_ImplicitConfig, RejectingStepsParsesIsBoundedAndNeedsParticipantsThatRepeat) {
  const std::string power = "power=[{name: p, force: b.f, velocity: a.x}]";
  const std::string adaptive = "coupling.adaptive={min_step: 1.0e-4, max_step: 1.0e-2}";
  EXPECT_EQ(parse({power, adaptive}).coupling.adaptive.reject_above, 0);  // default: never
  const auto c = parse({power, adaptive, "coupling.adaptive.reject_above=3"});
  EXPECT_EQ(c.coupling.adaptive.reject_above, 3);
  for (const char* bad : {"0.5", "-1", "1.0e7"}) {
    const auto m = error({power, adaptive, std::string("coupling.adaptive.reject_above=") + bad});
    EXPECT_NE(m.find("coupling.adaptive.reject_above: " + std::string(bad[0] == '1' ? "1e+07" : bad) +
                     " is not allowed (allowed: 0, never reject"),
              std::string::npos) << bad << ": " << m;
  }
  EXPECT_NE(error({power, adaptive, "coupling.adaptive.reject_above=nan"}).find("coupling.adaptive.reject_above: expected a finite number"),
            std::string::npos);
  // Explicit or implicit inside: a participant that cannot repeat a step is refused by name.
  std::map<std::string, cosim::ParticipantInfo> infos;
  infos["a"].can_repeat = true;
  infos["a"].inner_step = cosim::Duration(1000000);
  infos["b"].can_repeat = false;
  infos["b"].repeat_note = "an FMU without state";
  infos["b"].inner_step = cosim::Duration(1000000);
  auto a = master::make_algorithm(c);
  a->setup(c);
  try {
    a->initialize({&infos, 0});
    FAIL() << "rejecting steps with a participant that cannot repeat one was accepted";
  } catch (const cosim::config::ConfigError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("coupling.adaptive.reject_above"), std::string::npos) << m;
    EXPECT_NE(m.find("participant 'b' cannot repeat a step (an FMU without state)"), std::string::npos) << m;
  }
  infos["b"].can_repeat = true;
  EXPECT_NO_THROW(a->initialize({&infos, 0}));
  // Without reject_above the same participant is fine (every step is accepted).
  infos["b"].can_repeat = false;
  const auto c0 = parse({power, adaptive});
  auto b = master::make_algorithm(c0);
  b->setup(c0);
  EXPECT_NO_THROW(b->initialize({&infos, 0}));
}

TEST(master_ImplicitConfig, GaussSeidelFeedsBackOnlyTheConnectionsIntoEarlierParticipants) {
  master::ImplicitAlgorithm gs, jacobi;
  gs.setup(parse({"scheme=gauss_seidel", "order=[a, b]", "coupling.type=implicit", kConv}));
  jacobi.setup(parse({"coupling.type=implicit", kConv}));
  EXPECT_EQ(gs.fed_back(), std::vector<std::size_t>{1});  // b.f -> a.f; a.x -> b.x is fresh
  EXPECT_EQ(jacobi.fed_back(), (std::vector<std::size_t>{0, 1}));
}

// ---- accelerations on x = H(x) = A x + b, fixed point x* = (I - A)^-1 b ----

namespace {

std::vector<double> H2(const std::vector<double>& x) {  // |eig(A)| > 1: plain iteration diverges
  return {1.5 * x[0] - 0.8 * x[1] + 1.0, 0.6 * x[0] + 1.2 * x[1] - 2.0};
}

int iterate(master::Acceleration& acc, std::vector<double> x, int max, std::vector<double>& out) {
  acc.start_step({1.0, 1.0});
  for (int k = 0; k < max; ++k) {
    const auto y = H2(x);
    const double r = std::hypot(y[0] - x[0], y[1] - x[1]);
    if (r < 1e-10) {
      out = x;
      return k + 1;
    }
    x = acc.next(x, y, k);
  }
  out = x;
  return -1;
}

}  // namespace

TEST(master_Acceleration, IqnIlsSolvesALinearProblemInDimensionPlusTwoIterations) {
  // Fixed point of H2: (I - A) x = b  ->  [-0.5 0.8; -0.6 -0.2] x = [1; -2]
  const double det = -0.5 * -0.2 - 0.8 * -0.6;  // 0.58
  const std::vector<double> star = {(1.0 * -0.2 - 0.8 * -2.0) / det, (-0.5 * -2.0 - -0.6 * 1.0) / det};
  master::IqnIls iqn(0.1, 0, 10, 1e-6);
  std::vector<double> x;
  const int its = iterate(iqn, {0, 0}, 20, x);
  // One relaxation step, then the secant columns span the 2-d space after 2 more: exact.
  EXPECT_GE(its, 1);
  EXPECT_LE(its, 4);
  EXPECT_NEAR(x[0], star[0], 1e-8);
  EXPECT_NEAR(x[1], star[1], 1e-8);
  // Plain iteration diverges on the same problem.
  master::ConstantRelaxation plain(1.0);
  EXPECT_EQ(iterate(plain, {0, 0}, 50, x), -1);
  // With reuse, the next macro step starts from the kept columns: two iterations.
  master::IqnIls reuse(0.1, 2, 10, 1e-6);
  iterate(reuse, {0, 0}, 20, x);
  reuse.end_step();
  EXPECT_LE(iterate(reuse, {5, 5}, 20, x), 2);
  EXPECT_NEAR(x[0], star[0], 1e-8);
}

TEST(master_Acceleration, AitkenIsTheSecantMethodInOneDimension) {
  // x = H(x) = -3 x + 4, x* = 1; plain iteration diverges (|-3| > 1).
  master::AitkenRelaxation aitken(0.1);
  aitken.start_step({1.0});
  std::vector<double> x = {0};
  for (int k = 0; k < 2; ++k) x = aitken.next(x, {-3 * x[0] + 4}, k);
  EXPECT_NEAR(x[0], 1.0, 1e-12);  // exact after the first secant step
  EXPECT_NEAR(aitken.omega(), 0.25, 1e-12);  // 1 / (1 - (-3))
}

TEST(master_Acceleration, TheQrFilterDropsADependentColumn) {
  // Two iterations along the same direction give parallel columns: the filter keeps one.
  master::IqnIls iqn(0.5, 0, 10, 1e-2);
  iqn.start_step({1.0, 1.0});
  auto H = [](const std::vector<double>& x) { return std::vector<double>{0.5 * x[0] + 1, 0.5 * x[1] + 1}; };
  std::vector<double> x = {0, 0};
  x = iqn.next(x, H(x), 0);
  x = iqn.next(x, H(x), 1);
  EXPECT_EQ(iqn.columns_used(), 1);
  x = iqn.next({x[0], x[1]}, H(x), 2);  // the fixed point (2, 2) is on the same line
  EXPECT_EQ(iqn.columns_used(), 1);  // the second column is parallel to the first: filtered
  EXPECT_NEAR(x[0], 2.0, 1e-9);
  EXPECT_NEAR(x[1], 2.0, 1e-9);
}

// step_request_t.no_redo is sent for the steps no algorithm will do again: implicit coupling
// redoes every step, an adaptive step with reject_above may redo any, one without it as often
// as the fixed step inside it (here never: order 0, nothing to iterate at start-up).
TEST(master_ImplicitConfig, ImplicitAndRejectingAlgorithmsMayRepeatEveryStep) {
  std::map<std::string, cosim::ParticipantInfo> infos;
  for (const char* n : {"a", "b"}) {
    infos[n].can_repeat = true;
    infos[n].inner_step = cosim::Duration(1000000);
  }
  const auto implicit = parse({"coupling.type=implicit", kConv});
  master::ImplicitAlgorithm alg;
  alg.setup(implicit);
  alg.initialize({&infos, 1});
  EXPECT_TRUE(alg.may_repeat(0));
  EXPECT_TRUE(alg.may_repeat(1000));
  const std::string power = "power=[{name: p, force: b.f, velocity: a.x}]";
  const std::string adaptive = "coupling.adaptive={min_step: 1.0e-4, max_step: 1.0e-2}";
  const auto rejecting = parse({power, adaptive, "coupling.adaptive.reject_above=3"});
  auto r = master::make_algorithm(rejecting);
  r->setup(rejecting);
  r->initialize({&infos, 0});
  EXPECT_TRUE(r->may_repeat(1000));
  const auto accepting = parse({power, adaptive});
  auto a = master::make_algorithm(accepting);
  a->setup(accepting);
  a->initialize({&infos, 0});
  EXPECT_FALSE(a->may_repeat(0));
  EXPECT_FALSE(a->may_repeat(1000));
}
