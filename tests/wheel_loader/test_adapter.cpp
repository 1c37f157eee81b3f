// wheel_loader_adapter's Model: config layering and validation, ports, input limits, and a
// step repeated from a snapshot bit for bit.
#include <cosim/participant_core.hpp>
#include <cosim/yaml_config.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>

#include "config.hpp"  // master/src: the macro-step check
#include "wheel_loader_adapter.hpp"

using namespace wheel_loader;
using cosim::Duration;
using cosim::TimePoint;
using cosim::nanoseconds;

namespace {

const std::string kMachine = std::string(SOURCE_DIR) + "/configs/wheel_loader/machine.yaml";

cosim::RunInfo run_info(Duration macro = nanoseconds(1'000'000)) {
  return {"loader", TimePoint{}, cosim::time_point_ns(20'000'000'000), macro};
}

YAML::Node params(const std::string& yaml) { return YAML::Load(yaml); }

// The config error message for these parameters (empty if accepted).
std::string refusal(const std::string& yaml, Duration macro = nanoseconds(1'000'000)) {
  WheelLoaderAdapter m(cosim::config::load_file(kMachine));
  try {
    m.configure(params(yaml), run_info(macro));
  } catch (const cosim::config::ConfigError& e) {
    return e.what();
  }
  return "";
}

cosim::Polynomials wrench(double fx, double fz, double ty, const cosim::Vec3& point,
                          double dfx = 0) {
  cosim::InputPolynomial p;
  p.kind = cosim::SignalKind::Wrench;
  p.n_coefficients = 2;
  p.coefficients = cosim::Wrench{{fx, 0, fz}, {0, ty, 0}, point}.to_value();
  const cosim::Value slope = cosim::Wrench{{dfx, 0, 0}, {}, {}}.to_value();
  p.coefficients.insert(p.coefficients.end(), slope.begin(), slope.end());
  return {{"bucket_wrench", p}};
}

cosim::Vec3 bucket_position(const cosim::Signals& outputs) {
  return cosim::Kinematics::from_value(outputs.at("bucket").value).position;
}

}  // namespace

TEST(wheel_loader_adapter, MachineYamlHoldsTheDefaults) {
  EXPECT_TRUE(read_parameters(cosim::config::load_file(kMachine)) == Parameters{})
      << "configs/wheel_loader/machine.yaml and parameters.hpp disagree";
}

TEST(wheel_loader_adapter, RefusesBadKeysAndValuesNamingThem) {
  EXPECT_EQ(refusal("{}"), "");
  EXPECT_EQ(refusal("{boom.mass: 3000, maneuver.speed: [[0, 1.0]]}"), "");
  const std::pair<std::string, std::string> cases[] = {
      {"{boom.mas: 3000}", "unknown key 'mas'"},
      {"{bucket.mass: 0}", "bucket.mass"},
      {"{bucket.mass: heavy}", "bucket.mass"},
      {"{inner_step: -1e-4}", "inner_step"},
      {"{drive.traction_coefficient: 3}", "drive.traction_coefficient"},
      {"{boom.inertia: [1, 1, 5]}", "boom.inertia"},
      {"{maneuver.tilt: [[1, 0], [0.5, 0.1]]}", "maneuver.tilt.1"},
      {"{maneuver.interpolation: cubic}", "maneuver.interpolation"},
      {"{bucket.shape.edge_x: 0.3}", "bucket.shape.edge_x"},
      {"{lift_cylinder.frame_pin: [1, 2, 3]}", "lift_cylinder.frame_pin"},
      {"{limits.max_force: -1}", "limits.max_force"},
      {"{maneuver.tilt: [[0, 1.9]]}", "Z-bar linkage cannot close"},
  };
  for (const auto& [yaml, key] : cases) {
    const std::string e = refusal(yaml);
    EXPECT_NE(e.find(key), std::string::npos) << yaml << " -> '" << e << "'";
  }
}

// An inner step that does not divide the 1 ms macro step: the adapter declares it, the
// master's one macro-step check refuses it before the first step, naming both.
TEST(wheel_loader_adapter, InnerStepThatDoesNotDivideTheMacroStepIsRefused) {
  WheelLoaderAdapter m(cosim::config::load_file(kMachine));
  m.configure(params("{inner_step: 3e-4}"), run_info());
  master::Config c;
  c.macro_step = run_info().macro_step;
  cosim::ParticipantInfo info;
  info.inner_step = m.inner_step();
  try {
    master::check_wiring(c, {{"loader", info}});
    FAIL() << "accepted";
  } catch (const cosim::config::ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("time.macro_step: 1000000 ns is not a multiple of participant loader's "
                       "inner step 300000 ns"),
              std::string::npos)
        << msg;
  }
}

TEST(wheel_loader_adapter, PortsAndInitialOutputs) {
  WheelLoaderAdapter m(cosim::config::load_file(kMachine));
  m.configure(params("{}"), run_info());
  EXPECT_EQ(m.inner_step(), nanoseconds(100'000));
  ASSERT_EQ(m.inputs().size(), 1u);
  EXPECT_EQ(m.inputs()[0].name, "bucket_wrench");
  EXPECT_EQ(m.inputs()[0].kind, cosim::SignalKind::Wrench);
  const auto out = m.initial_outputs();
  cosim::check_against_ports(out, m.outputs(), "initial outputs");
  for (const char* n : {"bucket", "a_long", "a_vert", "j_long", "j_vert", "lift_force",
                        "tilt_force", "speed", "x_machine", "drive_force"})
    EXPECT_TRUE(out.count(n)) << n;
  const auto& b = out.at("bucket").value;
  cosim::validate_value(cosim::SignalKind::Kinematics, b, "bucket");
  const auto k = cosim::Kinematics::from_value(b);
  // at rest in equilibrium, moving at 1.2 m/s, bucket frame origin at the A-pin
  EXPECT_NEAR(k.velocity[0], 1.2, 1e-9);
  EXPECT_NEAR(out.at("speed").value[0], 1.2, 1e-9);
  EXPECT_NEAR(k.position[0], 2.6, 0.01);
  EXPECT_NEAR(out.at("edge_z").value[0], 0.05, 0.01);  // bucket just above the ground
}

TEST(wheel_loader_adapter, RefusesAnInsaneWrenchAndKeepsItsState) {
  WheelLoaderAdapter m(cosim::config::load_file(kMachine));
  m.configure(params("{}"), run_info());
  const TimePoint t1 = cosim::time_point_ns(1'000'000);
  const cosim::Vec3 x0 = bucket_position(m.initial_outputs());
  const auto bad = wrench(-6e6, 0, 0, x0);
  m.save_snapshot();
  EXPECT_THROW(m.step(cosim::StepInputs(TimePoint{}, t1, bad), false), cosim::InputError);
  m.restore_snapshot();  // as ParticipantCore does after an InputError
  const auto far = wrench(-1e5, 0, 0, {x0[0] + 1000, x0[1], x0[2] + 300});  // torque 3e7 N m
  EXPECT_THROW(m.step(cosim::StepInputs(TimePoint{}, t1, far), false), cosim::InputError);
  const auto ok = wrench(-1e5, 0, 0, x0);
  const auto r = m.step(cosim::StepInputs(TimePoint{}, t1, ok), false);
  EXPECT_NEAR(r.outputs.at("x_machine").value[0], 1.2e-3, 1e-4);
}

// The master's iterations: a step redone from the snapshot gives the same bits; an average
// is the trapezoid mean of the inner samples.
TEST(wheel_loader_adapter, SnapshotRepeatsAStepBitForBit) {
  WheelLoaderAdapter m(cosim::config::load_file(kMachine));
  m.configure(params("{initial_speed: 1.2}"), run_info(nanoseconds(2'000'000)));
  const cosim::Vec3 ref = bucket_position(m.initial_outputs());
  const Duration H = nanoseconds(2'000'000);
  TimePoint t{};
  for (int i = 0; i < 5; ++i, t += H)
    m.step(cosim::StepInputs(t, t + H, wrench(-5e4, 2e4, 1e3, ref, -1e4)), false);
  m.save_snapshot();
  const auto in = wrench(-8e4, 3e4, -2e3, ref, 2e4);
  const auto first = m.step(cosim::StepInputs(t, t + H, in), true);
  m.restore_snapshot();
  const auto other = m.step(cosim::StepInputs(t, t + H, wrench(0, 0, 0, ref)), false);
  m.restore_snapshot();
  const auto again = m.step(cosim::StepInputs(t, t + H, in), true);
  ASSERT_TRUE(first.average && again.average);
  for (const auto& [name, s] : first.outputs) {
    EXPECT_EQ(s.value, again.outputs.at(name).value) << name;  // bitwise
    EXPECT_EQ(first.average->at(name).value, again.average->at(name).value) << name;
  }
  // the input matters (so the equality above is not vacuous)
  EXPECT_NE(first.outputs.at("a_long").value, other.outputs.at("a_long").value);
  // the average lies between the start and end values for the monotone x position
  const double xa = first.average->at("x_machine").value[0];
  const double xe = first.outputs.at("x_machine").value[0];
  EXPECT_LT(xa, xe);
  EXPECT_GT(xa, xe - 2e-3 * 1.3);
}

// Checkpoints (cosim_master --resume): a model restored from the checkpoint after 5 steps in a
// fresh process continues bit for bit like the model that never stopped.
TEST(wheel_loader_adapter, CheckpointRestoresTheStateBitForBit) {
  const std::string path = ::testing::TempDir() + "wheel_loader_checkpoint.ckpt";
  const Duration H = nanoseconds(2'000'000);
  WheelLoaderAdapter m(cosim::config::load_file(kMachine));
  m.configure(params("{initial_speed: 1.2}"), run_info(H));
  ASSERT_TRUE(m.can_checkpoint());
  const cosim::Vec3 ref = bucket_position(m.initial_outputs());
  auto input = [&](int i) { return wrench(-5e4 - 3e3 * i, 2e4 + 1e3 * i, 1e3 * (i % 3), ref, -1e4); };
  TimePoint t{};
  for (int i = 0; i < 5; ++i, t += H) m.step(cosim::StepInputs(t, t + H, input(i)), false);
  m.save_checkpoint(path);
  cosim::RunInfo resume = run_info(H);
  resume.resume_steps_done = 5;
  resume.resume_time = t;
  WheelLoaderAdapter r(cosim::config::load_file(kMachine));
  r.configure(params("{initial_speed: 1.2}"), resume);
  r.load_checkpoint(path);
  for (int i = 5; i < 10; ++i, t += H) {
    const auto in = input(i);
    const auto a = m.step(cosim::StepInputs(t, t + H, in), i % 2 == 0);
    const auto b = r.step(cosim::StepInputs(t, t + H, in), i % 2 == 0);
    for (const auto& [name, s] : a.outputs) EXPECT_EQ(s.value, b.outputs.at(name).value) << name << " step " << i;
    if (a.average) {
      for (const auto& [name, s] : *a.average) EXPECT_EQ(s.value, b.average->at(name).value) << name;
    }
    ASSERT_EQ(a.diagnostics.size(), b.diagnostics.size());
    for (std::size_t k = 0; k < a.diagnostics.size(); ++k) EXPECT_EQ(a.diagnostics[k].second, b.diagnostics[k].second);
  }
  // not vacuous: a model that was not restored is elsewhere
  WheelLoaderAdapter fresh(cosim::config::load_file(kMachine));
  fresh.configure(params("{initial_speed: 1.2}"), run_info(H));
  EXPECT_NE(bucket_position(fresh.initial_outputs())[0], bucket_position(m.initial_outputs())[0]);
  // a checkpoint of another time or another model is refused, naming why
  cosim::RunInfo later = resume;
  later.resume_time = t;
  WheelLoaderAdapter w(cosim::config::load_file(kMachine));
  w.configure(params("{initial_speed: 1.2}"), later);
  try {
    w.load_checkpoint(path);
    ADD_FAILURE() << "a checkpoint of another time was taken";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("its state is at t = 0.010000 s, the resume at 0.020000 s"), std::string::npos) << e.what();
  }
  std::ofstream(path) << "mbs_state 1 hauler\nt 0x0p+0\n";
  try {
    w.load_checkpoint(path);
    ADD_FAILURE() << "a hauler's checkpoint was taken";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("it is a hauler's state, this is a wheel_loader"), std::string::npos) << e.what();
  }
}
