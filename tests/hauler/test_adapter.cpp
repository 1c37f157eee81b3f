// hauler_adapter's Model: the machine file holds the defaults, bad config values are refused
// naming the key, ports, input limits, a step repeated from a snapshot bit for bit, and a
// discharge-like run at the 1 ms macro step with the wrench constant over each step.
#include <cosim/participant.hpp>
#include <cosim/yaml_config.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <cstdio>
#include <string>

#include "config.hpp"  // master/src: the macro-step check
#include "hauler_adapter.hpp"

using namespace hauler;
using cosim::Duration;
using cosim::TimePoint;
using cosim::nanoseconds;

namespace {

const std::string kMachine = std::string(SOURCE_DIR) + "/configs/hauler/machine.yaml";

cosim::RunInfo run_info(Duration macro = nanoseconds(1'000'000)) {
  return {"hauler", TimePoint{}, cosim::time_point_ns(40'000'000'000), macro};
}

// The config error message for these parameters (empty if accepted).
std::string refusal(const std::string& yaml) {
  HaulerAdapter m(cosim::config::load_file(kMachine));
  try {
    m.configure(YAML::Load(yaml), run_info());
  } catch (const cosim::config::ConfigError& e) {
    return e.what();
  }
  return "";
}

// A wrench constant over the step (one coefficient): force f at `point`, no torque.
cosim::Polynomials wrench(const cosim::Vec3& f, const cosim::Vec3& point) {
  cosim::InputPolynomial p;
  p.kind = cosim::SignalKind::Wrench;
  p.n_coefficients = 1;
  p.coefficients = cosim::Wrench{f, {0, 0, 0}, point}.to_value();
  return {{"body_wrench", p}};
}

double scalar(const cosim::Signals& s, const std::string& name) { return s.at(name).value.at(0); }

}  // namespace

TEST(hauler_adapter, MachineYamlHoldsTheDefaults) {
  EXPECT_TRUE(read_parameters(cosim::config::load_file(kMachine)) == Parameters{})
      << "configs/hauler/machine.yaml and parameters.hpp disagree";
}

TEST(hauler_adapter, RefusesBadKeysAndValuesNamingThem) {
  EXPECT_EQ(refusal("{}"), "");
  EXPECT_EQ(refusal("{test_payload: {mass: 39000, com: [2.6, 1.1]}, tipping.angle: [[0, 0], [4, 30]]}"), "");
  EXPECT_EQ(refusal("{tipping.mode: length, tipping.length: [[0, 1.3], [10, 4.0]]}"), "");
  const std::pair<std::string, std::string> cases[] = {
      {"{dump_body.mas: 3000}", "unknown key 'mas'"},
      {"{suspension.front.polytropic: 0.8}", "suspension.front.polytropic"},
      {"{suspension.rear.accumulator_volume: 12}", "suspension.rear.accumulator_volume"},
      {"{suspension.ride_stroke: 0.19}", "suspension.ride_stroke"},
      {"{tires.stiffness: -1.0e6}", "tires.stiffness"},
      {"{tires.stiffness: stiff}", "tires.stiffness"},
      {"{axles.rear1.x: 0.5}", "axles.rear1.x"},
      {"{dump_body.hinge: [-6.0, 1.25]}", "dump_body.hinge"},
      {"{hoist.frame_pin: [1, 2, 3]}", "hoist.frame_pin"},
      {"{tipping.angle: [[0, 0], [10, 95]]}", "tipping.angle.1"},
      {"{tipping.angle: [[5, 0], [2, 30]]}", "tipping.angle.1"},
      {"{tipping.mode: length}", "tipping.length: missing"},
      {"{tipping.mode: length, tipping.length: [[0, 0.5]]}", "tipping.length.0"},
      {"{tipping.interpolation: cubic}", "tipping.interpolation"},
      {"{brake.friction: 0}", "brake.friction"},
      {"{inner_step: 2e-3}", "inner_step"},
      {"{test_payload: {mass: -5}}", "test_payload.mass"},
      {"{dump_body.shape.length: 0.3}", "dump_body.shape.length"},
      {"{front_unit.inertia: [1, 1, 5]}", "front_unit.inertia"},
  };
  for (const auto& [yaml, key] : cases) {
    const std::string e = refusal(yaml);
    EXPECT_NE(e.find(key), std::string::npos) << yaml << " -> '" << e << "'";
  }
}

// An inner step that does not divide the 1 ms macro step: the master's check refuses it.
TEST(hauler_adapter, InnerStepThatDoesNotDivideTheMacroStepIsRefused) {
  HaulerAdapter m(cosim::config::load_file(kMachine));
  m.configure(YAML::Load("{inner_step: 3e-4}"), run_info());
  master::Config c;
  c.macro_step = run_info().macro_step;
  cosim::ParticipantInfo info;
  info.inner_step = m.inner_step();
  EXPECT_THROW(master::check_wiring(c, {{"hauler", info}}), cosim::config::ConfigError);
}

TEST(hauler_adapter, PortsAndInitialOutputs) {
  HaulerAdapter m(cosim::config::load_file(kMachine));
  m.configure(YAML::Load("{}"), run_info());
  EXPECT_EQ(m.inner_step(), nanoseconds(200'000));
  ASSERT_EQ(m.inputs().size(), 1u);
  EXPECT_EQ(m.inputs()[0].name, "body_wrench");
  EXPECT_EQ(m.inputs()[0].kind, cosim::SignalKind::Wrench);
  std::vector<std::string> names;
  for (const auto& p : m.outputs()) names.push_back(p.name);
  const std::vector<std::string> expected{
      "body",         "front_fx",     "front_fz",       "rear1_fx",      "rear1_fz",
      "rear2_fx",     "rear2_fz",     "front_stroke",   "rear1_stroke",  "rear2_stroke",
      "front_pressure", "rear_pressure", "hoist_force", "body_angle"};
  EXPECT_EQ(names, expected);
  EXPECT_EQ(m.outputs()[0].kind, cosim::SignalKind::Kinematics);
  const auto out = m.initial_outputs();
  cosim::check_against_ports(out, m.outputs(), "initial outputs");
  const auto k = cosim::Kinematics::from_value(out.at("body").value);
  // the body frame origin is the hinge: chassis (-7.2, 1.25) on a chassis standing on its
  // tires (unloaded radius 0.89 m less the empty machine's deflection, 3-6 cm; the front
  // tires deflect more, so the empty machine sits 0.006 rad nose down and the hinge is higher)
  std::printf("body origin (%.4f, %.4f, %.4f), q (%.6f %.6f %.6f %.6f)\n", k.position[0],
              k.position[1], k.position[2], k.orientation[0], k.orientation[1], k.orientation[2],
              k.orientation[3]);
  EXPECT_NEAR(k.position[0], -7.2, 0.01);
  EXPECT_NEAR(k.position[1], 0.0, 1e-12);
  EXPECT_NEAR(k.position[2], 1.25 + 0.89 - 0.04, 0.05);
  for (double v : k.velocity) EXPECT_NEAR(v, 0.0, 1e-12);
  EXPECT_NEAR(k.orientation[0], 1.0, 1e-4);  // nearly level, body lowered
  const double W = m.model().total_mass() * 9.81;
  EXPECT_NEAR(scalar(out, "front_fz") + scalar(out, "rear1_fz") + scalar(out, "rear2_fz"), W, 1e-6 * W);
  EXPECT_NEAR(scalar(out, "rear1_fz"), scalar(out, "rear2_fz"), 1e-3 * W);
  EXPECT_NEAR(scalar(out, "front_stroke"), 0.10, 1e-9);
  EXPECT_NEAR(scalar(out, "body_angle"), 0.0, 0.01);

  HaulerAdapter with(cosim::config::load_file(kMachine));
  with.configure(YAML::Load("{test_payload: {mass: 39000}}"), run_info());
  EXPECT_EQ(with.outputs().back().name, "payload_rigid");
  EXPECT_EQ(scalar(with.initial_outputs(), "payload_rigid"), 39000.0);
}

TEST(hauler_adapter, RefusesAnInsaneWrenchAndKeepsItsState) {
  HaulerAdapter m(cosim::config::load_file(kMachine));
  m.configure(YAML::Load("{}"), run_info());
  const TimePoint t1 = cosim::time_point_ns(1'000'000);
  const cosim::Vec3 x0 = cosim::Kinematics::from_value(m.initial_outputs().at("body").value).position;
  m.save_snapshot();
  EXPECT_THROW(m.step(cosim::StepInputs(TimePoint{}, t1, wrench({0, 0, -6e6}, x0)), false),
               cosim::InputError);
  m.restore_snapshot();
  EXPECT_THROW(m.step(cosim::StepInputs(TimePoint{}, t1, wrench({0, 0, -4e5}, {x0[0] + 100, 0, x0[2]})), false),
               cosim::InputError);  // torque 4e7 N m about the body origin
  m.restore_snapshot();
  const auto r = m.step(cosim::StepInputs(TimePoint{}, t1, wrench({0, 0, -3.8e5}, {x0[0] + 2.6, 0, x0[2] + 1.1})), false);
  EXPECT_TRUE(std::isfinite(scalar(r.outputs, "rear1_fz")));
}

// The master's iterations: a step redone from the snapshot gives the same bits, outputs and
// averages; the input matters.
TEST(hauler_adapter, SnapshotRepeatsAStepBitForBit) {
  HaulerAdapter m(cosim::config::load_file(kMachine));
  m.configure(YAML::Load("{tipping.angle: [[0, 0], [0.01, 0], [1, 20]]}"), run_info());
  const cosim::Vec3 o = cosim::Kinematics::from_value(m.initial_outputs().at("body").value).position;
  const Duration H = nanoseconds(1'000'000);
  TimePoint t{};
  for (int i = 0; i < 20; ++i, t += H)
    m.step(cosim::StepInputs(t, t + H, wrench({-1e4, 0, -2e5}, {o[0] + 2.6, 0, o[2] + 1.1})), false);
  m.save_snapshot();
  const auto in = wrench({-3e4, 500, -2.5e5}, {o[0] + 2.0, 0.1, o[2] + 1.0});
  const auto first = m.step(cosim::StepInputs(t, t + H, in), true);
  m.restore_snapshot();
  const auto other = m.step(cosim::StepInputs(t, t + H, wrench({0, 0, 0}, o)), true);
  m.restore_snapshot();
  const auto again = m.step(cosim::StepInputs(t, t + H, in), true);
  ASSERT_TRUE(first.average && again.average);
  for (const auto& [name, s] : first.outputs) {
    EXPECT_EQ(s.value, again.outputs.at(name).value) << name;  // bitwise
    EXPECT_EQ(first.average->at(name).value, again.average->at(name).value) << name;
  }
  ASSERT_EQ(first.diagnostics.size(), again.diagnostics.size());
  for (std::size_t i = 0; i < first.diagnostics.size(); ++i)
    EXPECT_EQ(first.diagnostics[i].second, again.diagnostics[i].second) << first.diagnostics[i].first;
  EXPECT_NE(first.outputs.at("rear2_fz").value, other.outputs.at("rear2_fz").value);
  // the body angle rises through the step: its average lies between start and end
  const double a_end = scalar(first.outputs, "body_angle"), a_avg = scalar(*first.average, "body_angle");
  EXPECT_LT(a_avg, a_end);
}

// A discharge without DEM at the 1 ms macro step: 39 t of payload as a weight on a body point,
// constant over each step, leaving the body between 8 and 12 s while the body tips (default
// profile). Stable, and what the paper describes: the loaded rear settles, the unloading lets
// the rear struts extend into their stop, the bogie stops sharing evenly, and the level control
// drains the rear circuit.
TEST(hauler_adapter, DischargeAtTheMacroStepIsStableAndHitsTheStrokeLimit) {
  HaulerAdapter m(cosim::config::load_file(kMachine));
  m.configure(YAML::Load("{static_load: {mass: 39000, com: [2.6, 1.1]}}"), run_info());
  const Parameters& p = m.model().parameters();
  const Duration H = nanoseconds(1'000'000);
  auto payload = [](double t) {  // kg left in the body
    const double s = std::clamp((t - 8.0) / 4.0, 0.0, 1.0);
    return 39000 * (1 - s * s * (3 - 2 * s));
  };
  TimePoint t{};
  double max_stroke = 0, min_stroke = 1, max_bogie_split = 0, front_min = 1e9;
  double rear_pressure_start = 0, rear_at_limit_time = -1;
  cosim::StepResult r;
  for (int i = 0; i < 16000; ++i, t += H) {
    const double ts = cosim::to_seconds(t);
    const cosim::Vec3 c = m.model().coupled_point({2.6, 0, 1.1});
    r = m.step(cosim::StepInputs(t, t + H, wrench({0, 0, -payload(ts) * 9.81}, c)), false);
    const auto& o = r.outputs;
    for (const char* n : {"front_stroke", "rear1_stroke", "rear2_stroke"}) {
      ASSERT_TRUE(std::isfinite(scalar(o, n))) << n << " at " << ts;
      max_stroke = std::max(max_stroke, scalar(o, n));
      min_stroke = std::min(min_stroke, scalar(o, n));
    }
    if (i == 0) rear_pressure_start = scalar(o, "rear_pressure");
    front_min = std::min(front_min, scalar(o, "front_fz"));
    const double split = std::abs(scalar(o, "rear1_fz") - scalar(o, "rear2_fz")) /
                         (scalar(o, "rear1_fz") + scalar(o, "rear2_fz"));
    max_bogie_split = std::max(max_bogie_split, split);
    if (rear_at_limit_time < 0 && scalar(o, "rear2_stroke") > p.suspension.stroke) rear_at_limit_time = ts;
  }
  const Reports end = m.model().reports();
  std::printf("discharge: strokes %.4f .. %.4f m, rear at its limit from %.2f s, bogie split up to %.1f %%, "
              "rear pressure %.2f -> %.2f MPa, rear oil flow at 16 s %.1e m3/s, body %.1f deg\n",
              min_stroke, max_stroke, rear_at_limit_time, 100 * max_bogie_split,
              rear_pressure_start / 1e6, end.rear.pressure / 1e6, end.rear.flow,
              end.body_angle * 180 / 3.14159265358979);
  EXPECT_GT(min_stroke, -3e-3);
  EXPECT_LT(max_stroke, p.suspension.stroke + 3e-3);
  EXPECT_GT(rear_at_limit_time, 8.0);   // the stroke limit comes with the unloading
  EXPECT_GT(max_bogie_split, 0.02);     // the bogie no longer shares evenly at the stop
  EXPECT_LT(end.rear.pressure, 0.5 * rear_pressure_start);
  EXPECT_LT(end.rear.flow, 0.0);        // the level control drains the rear circuit
  EXPECT_GT(front_min, 0.0);
}

// Checkpoints (cosim_master --resume): the bodies and the circuits' oil restored in a fresh
// model continue bit for bit.
TEST(hauler_adapter, CheckpointRestoresTheStateBitForBit) {
  const std::string path = ::testing::TempDir() + "hauler_checkpoint.ckpt";
  const char* params = "{tipping.angle: [[0, 0], [0.01, 0], [1, 20]]}";
  HaulerAdapter m(cosim::config::load_file(kMachine));
  m.configure(YAML::Load(params), run_info());
  ASSERT_TRUE(m.can_checkpoint());
  const cosim::Vec3 o = cosim::Kinematics::from_value(m.initial_outputs().at("body").value).position;
  const Duration H = nanoseconds(1'000'000);
  auto input = [&](int i) { return wrench({-1e4 - 500.0 * i, 0, -2e5 - 1e3 * i}, {o[0] + 2.6, 0, o[2] + 1.1}); };
  TimePoint t{};
  for (int i = 0; i < 20; ++i, t += H) m.step(cosim::StepInputs(t, t + H, input(i)), false);
  m.save_checkpoint(path);
  cosim::RunInfo resume = run_info();
  resume.resume_steps_done = 20;
  resume.resume_time = t;
  HaulerAdapter r(cosim::config::load_file(kMachine));
  r.configure(YAML::Load(params), resume);
  r.load_checkpoint(path);
  for (int i = 20; i < 30; ++i, t += H) {
    const auto a = m.step(cosim::StepInputs(t, t + H, input(i)), true);
    const auto b = r.step(cosim::StepInputs(t, t + H, input(i)), true);
    for (const auto& [name, s] : a.outputs) EXPECT_EQ(s.value, b.outputs.at(name).value) << name << " step " << i;
    for (const auto& [name, s] : *a.average) EXPECT_EQ(s.value, b.average->at(name).value) << name;
    ASSERT_EQ(a.diagnostics.size(), b.diagnostics.size());
    for (std::size_t k = 0; k < a.diagnostics.size(); ++k)
      EXPECT_EQ(a.diagnostics[k].second, b.diagnostics[k].second) << a.diagnostics[k].first;
  }
  std::ofstream(path) << "mbs_state 1 wheel_loader\nt 0x0p+0\n";
  try {
    r.load_checkpoint(path);
    ADD_FAILURE() << "a wheel loader's checkpoint was taken";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("it is a wheel_loader's state, this is a hauler"), std::string::npos) << e.what();
  }
}
