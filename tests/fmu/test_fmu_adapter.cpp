// fmu_adapter: the Reference FMUs (../shared/fmus, skipped when absent) as participants of
// cosim_master over LCM against their reference CSVs; repeated steps through the FMU state bit
// for bit; an FMU without state support refused for start-up iterations; broken FMUs (repacked
// from good ones in a temp folder) and an FMU that fails mid-run, each with its message.
#include <cmath>
#include <cstring>
#include <regex>

#include <cosim/bus.hpp>

#include "../oscillator/harness.hpp"
#include "euler.hpp"
#include "fmu_model.hpp"
#include "fmu_test_util.hpp"

namespace {

using fmutest::Entries;

cosim::RunInfo run_info(double end = 1.0, double macro = 0.1, const std::string& name = "p") {
  return cosim::RunInfo{name, cosim::TimePoint{}, cosim::seconds_to_time_point(end, "end"),
                        cosim::seconds_to_duration(macro, "macro")};
}

YAML::Node yaml(const std::string& text) { return YAML::Load(text); }

// The message configure() raises for `fmu` with `mapping` (YAML text without the fmu key).
std::string configure_error(const std::string& fmu, const std::string& mapping = "outputs: [{name: x, scalar: x}]") {
  fmu::FmuModel m(YAML::Node(YAML::NodeType::Map), "");
  YAML::Node p = yaml(mapping);
  p["fmu"] = fmu;
  try {
    m.configure(p, run_info());
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

#define EXPECT_HAS(text, part) EXPECT_NE(std::string(text).find(part), std::string::npos) << "missing '" << (part) << "' in: " << (text)

// ---------------------------------------------------------------------------------------------
// Orientation as angles

TEST(FmuEuler, EverySequenceRoundTripsAndMatchesTheAxisProduct) {
  const char* sequences[] = {"xyz", "xzy", "yxz", "yzx", "zxy", "zyx", "xyx", "xzx", "yxy", "yzy", "zxz", "zyz"};
  for (const char* name : sequences) {
    const auto s = fmu::parse_sequence(name);
    for (const std::array<double, 3> a : {std::array<double, 3>{0.3, -0.7, 1.9}, {-2.5, 0.4, -0.1}, {1.0, 1.2, 3.0}}) {
      std::array<double, 3> in = a;
      if (s.axes[0] == s.axes[2]) in[1] = std::abs(in[1]);  // proper Euler: middle angle in [0, pi]
      const cosim::Quat q = fmu::quat_from_angles(s, in);
      const auto out = fmu::angles_from_quat(s, q);
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(out[i], in[i], 1e-12) << name;
    }
    // Gimbal lock: the rotation survives even where the angles are not unique.
    const double mid = s.axes[0] == s.axes[2] ? 0.0 : M_PI / 2;
    const cosim::Quat q = fmu::quat_from_angles(s, {0.4, mid, -0.3});
    const cosim::Quat back = fmu::quat_from_angles(s, fmu::angles_from_quat(s, q));
    const double dot = q[0] * back[0] + q[1] * back[1] + q[2] * back[2] + q[3] * back[3];
    EXPECT_NEAR(std::abs(dot), 1.0, 1e-12) << name;
  }
  // zyx with yaw 90 deg takes the body's x axis to ground y (R = Rz Ry Rx, body -> ground).
  const auto v = cosim::quat_rotate(fmu::quat_from_angles(fmu::parse_sequence("zyx"), {M_PI / 2, 0, 0}), {1, 0, 0});
  EXPECT_NEAR(v[0], 0, 1e-15);
  EXPECT_NEAR(v[1], 1, 1e-15);
  // zyx: yaw then pitch about the new y: the body x axis ends up pointing down-ish along ground y.
  const auto w = cosim::quat_rotate(fmu::quat_from_angles(fmu::parse_sequence("zyx"), {M_PI / 2, M_PI / 4, 0}), {1, 0, 0});
  EXPECT_NEAR(w[0], 0, 1e-15);
  EXPECT_NEAR(w[1], std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(w[2], -std::sqrt(0.5), 1e-15);
  EXPECT_THROW(fmu::parse_sequence("zzx"), std::invalid_argument);
  EXPECT_THROW(fmu::parse_sequence("abc"), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Broken FMUs, each from the good test-only FMU (always available) repacked in a temp folder.

TEST(FmuBroken, MissingFileAndNotAZip) {
  EXPECT_HAS(configure_error("/nonexistent/model.fmu"), "FMU '/nonexistent/model.fmu': file not found");
  const std::string text = fmutest::temp_path(".fmu");
  std::ofstream(text) << "this is not a zip archive\n";
  const std::string e = configure_error(text);
  EXPECT_HAS(e, "FMU '" + text + "': not a zip archive");
}

TEST(FmuBroken, MissingBinaryAndWrongPlatform) {
  Entries e = fmutest::fail_fmu_entries();
  e.pop_back();  // binaries/linux64/fail_fmu.so
  std::string msg = configure_error(fmutest::pack(e, "_nobin.fmu"));
  EXPECT_HAS(msg, "(model 'FailFmu')': no binary for this platform: binaries/linux64/fail_fmu.so is not in the archive");
  EXPECT_HAS(msg, "it has no binaries at all");  // binaries/linux64/ is there, empty
  EXPECT_HAS(msg, "export the FMU for linux64");

  Entries w = fmutest::fail_fmu_entries();
  for (auto& [n, d] : w) n = fmutest::replace_all(n, "linux64", "win64");
  w.back().first = "binaries/win64/fail_fmu.dll";
  msg = configure_error(fmutest::pack(w, "_win64.fmu"));
  EXPECT_HAS(msg, "no binary for this platform");
  EXPECT_HAS(msg, "it has binaries for: win64");

  Entries junk = fmutest::fail_fmu_entries();
  junk.back().second = "not an ELF file";
  msg = configure_error(fmutest::pack(junk, "_junk.fmu"));
  EXPECT_HAS(msg, "cannot load its binary");
}

TEST(FmuBroken, ModelDescriptionProblems) {
  auto with_xml = [](const std::string& from, const std::string& to, const std::string& suffix) {
    Entries e = fmutest::fail_fmu_entries();
    std::string& xml = fmutest::entry(e, "modelDescription.xml");
    const std::string before = xml;
    xml = fmutest::replace_all(xml, from, to);
    EXPECT_NE(xml, before) << from;
    return configure_error(fmutest::pack(e, suffix));
  };
  std::string msg = with_xml("</ModelVariables>", "</ModelVariable>", "_malformed.fmu");
  EXPECT_HAS(msg, "modelDescription.xml is malformed XML");
  EXPECT_HAS(msg, "at line");
  EXPECT_HAS(msg, "_malformed.fmu");
  msg = with_xml("fmiVersion=\"2.0\"", "fmiVersion=\"3.0\"", "_fmi3.fmu");
  EXPECT_HAS(msg, "fmiVersion is \"3.0\"; fmu_adapter imports FMI 2.0 only");
  msg = with_xml("fmiVersion=\"2.0\"", "fmiVersion=\"1.0\"", "_fmi1.fmu");
  EXPECT_HAS(msg, "fmiVersion is \"1.0\"");
  msg = with_xml("<CoSimulation modelIdentifier", "<ModelExchange modelIdentifier", "_me.fmu");
  EXPECT_HAS(msg, "no <CoSimulation> element: the FMU offers Model Exchange only");
  msg = with_xml("guid=\"{fail-fmu-test-0001}\"", "guid=\"{another}\"", "_guid.fmu");
  EXPECT_HAS(msg, "fmi2Instantiate failed");

  Entries none = fmutest::fail_fmu_entries();
  none.erase(none.begin());
  msg = configure_error(fmutest::pack(none, "_noxml.fmu"));
  EXPECT_HAS(msg, "no modelDescription.xml");
}

TEST(FmuBroken, MappingAgainstTheModelDescription) {
  const std::string good = fmutest::pack(fmutest::fail_fmu_entries());
  std::string msg = configure_error(good, "outputs: [{name: x, scalar: y}]");
  EXPECT_HAS(msg, "participants.p.parameters.outputs.0.scalar: FMU FmuBroken_MappingAgainstTheModelDescription.fmu (model 'FailFmu')");
  EXPECT_HAS(msg, "has no variable 'y'");
  EXPECT_HAS(msg, "outputs: x");
  EXPECT_HAS(msg, "parameters: fail_at, fail_status");
  msg = configure_error(good, "outputs: [{name: x, scalar: fail_att}]");
  EXPECT_HAS(msg, "did you mean 'fail_at'?");
  msg = configure_error(good, "{start: {nope: 1}, outputs: [{name: x, scalar: x}]}");
  EXPECT_HAS(msg, "participants.p.parameters.start.nope: FMU");
  EXPECT_HAS(msg, "has no variable 'nope'");
  msg = configure_error(good, "{inputs: [{name: u, scalar: x}], outputs: [{name: y, scalar: x}]}");
  EXPECT_HAS(msg, "inputs.0.scalar: 'x' has causality output; an input port sets variables with causality input");
  msg = configure_error(good, "{inputs: [{name: u, scalar: fail_at}], outputs: [{name: y, scalar: x}]}");
  EXPECT_HAS(msg, "(set parameters under `start`)");
  msg = configure_error(good, "outputs: [{name: t, scalar: time}]");
  EXPECT_HAS(msg, "is the independent variable");
  msg = configure_error(good, "{start: {fail_at: true}, outputs: [{name: x, scalar: x}]}");
  EXPECT_HAS(msg, "start.fail_at: 'fail_at' is an FMI Real variable; expected a finite number, got 'true'");
  msg = configure_error(good, "{start: {fail_status: 2.5}, outputs: [{name: x, scalar: x}]}");
  EXPECT_HAS(msg, "start.fail_status: 'fail_status' is an FMI Integer variable; expected an integer, got '2.5'");
  msg = configure_error(good, "{start: {x: 1}, outputs: [{name: x, scalar: x}]}");
  EXPECT_HAS(msg, "'x' is calculated by the FMU");
  msg = configure_error(good, "{outputs: [{name: w, wrench: {force: [x, 0, 0], torque: [0, 0, 0], reference_point: [0, 0, 0]}}]}");
  EXPECT_HAS(msg, "outputs.0.wrench.frame: missing");
  msg = configure_error(good, "{outputs: [{name: w, wrench: {force: [x, 0, 0], frame: tool, reference_point: [0, 0, 0]}}]}");
  EXPECT_HAS(msg, "outputs.0.wrench.frame: 'tool' is neither ground nor a kinematics port");
  msg = configure_error(good, "{outputs: [{name: k, kinematics: {orientation: {angles: [x, 0, 0], sequence: zzx}}}]}");
  EXPECT_HAS(msg, "orientation.sequence: 'zzx' turns about the same axis twice in a row");
  msg = configure_error(good, "{outputs: [{name: x, scalar: x}], substep: 2}");
  EXPECT_HAS(msg, "unknown key 'substep'");
  msg = configure_error(good, "{outputs: [{name: x, scalar: x}], substeps: 3}");
  EXPECT_HAS(msg, "substeps: the macro step of 100000000 ns does not split into 3 sub-steps of whole nanoseconds");
  msg = configure_error(good, "{outputs: [{name: x, scalar: x}], step_size: 0.03}");
  EXPECT_HAS(msg, "step_size: 0.030000 s does not divide the macro step 0.100000 s");
  msg = configure_error(good, "{inputs: [], outputs: []}");
  EXPECT_HAS(msg, "outputs: missing; map at least one FMU output");
}

// fmi2Error, fmi2Fatal and fmi2Discard from fmi2DoStep, in process: the step raises with the
// FMU, the instance, the call, the time and what the FMU logged; no later step runs.
TEST(FmuBroken, FailureMidRunInProcess) {
  const std::string good = fmutest::pack(fmutest::fail_fmu_entries());
  for (const auto& [status, name] : std::vector<std::pair<int, std::string>>{{3, "fmi2Error"}, {4, "fmi2Fatal"}, {2, "fmi2Discard"}}) {
    fmu::FmuModel m(YAML::Node(YAML::NodeType::Map), "");
    YAML::Node p = yaml("{instance: failing, start: {fail_at: 0.25, fail_status: " + std::to_string(status) +
                        "}, outputs: [{name: x, scalar: x}]}");
    p["fmu"] = good;
    m.configure(p, run_info());
    cosim::Polynomials none;
    for (int i = 0; i < 2; ++i) {
      const cosim::StepInputs in(cosim::seconds_to_time_point(0.1 * i, "t"), cosim::seconds_to_time_point(0.1 * (i + 1), "t"), none);
      const auto r = m.step(in, false);
      EXPECT_NEAR(r.outputs.at("x").value[0], 0.1 * (i + 1), 1e-15);
    }
    const cosim::StepInputs in(cosim::seconds_to_time_point(0.2, "t"), cosim::seconds_to_time_point(0.3, "t"), none);
    try {
      m.step(in, false);
      ADD_FAILURE() << "no error for " << name;
    } catch (const fmu::FmuError& e) {
      const std::string msg = e.what();
      EXPECT_HAS(msg, "FMU 'FmuBroken_FailureMidRunInProcess.fmu (model 'FailFmu')' (instance 'failing'): fmi2DoStep at t = 0.2 s (step 0.1 s) returned " + name);
      EXPECT_HAS(msg, "deliberate failure: the step from t = 0.2 to 0.3 passes fail_at = 0.25");
    }
    EXPECT_THROW(m.step(in, false), fmu::FmuError);  // no second try on a failed instance
  }
}

// The test-only FMU without FMU-state support cannot repeat; its note says why.
TEST(FmuState, WithoutStateSupportTheModelSaysSo) {
  fmu::FmuModel m(YAML::Node(YAML::NodeType::Map), "");
  YAML::Node p = yaml("outputs: [{name: x, scalar: x}]");
  p["fmu"] = fmutest::pack(fmutest::fail_fmu_entries());
  m.configure(p, run_info());
  EXPECT_FALSE(m.can_repeat());
  EXPECT_HAS(m.repeat_note(), "declares canGetAndSetFMUstate=\"false\"");
}

// ---------------------------------------------------------------------------------------------
// Ports: the echo FMU copies its inputs to its outputs at each doStep, so what a port sets can
// be read back raw (y0..y15) and through an output port of the same shape.

struct Echo {
  fmu::FmuModel model{YAML::Node(YAML::NodeType::Map), ""};
  explicit Echo(const std::string& mapping, const std::string& name = "echo") {
    YAML::Node p = yaml(mapping);
    p["fmu"] = fmutest::pack(fmutest::echo_fmu_entries(), "_" + name + ".fmu");
    model.configure(p, run_info(1.0, 0.1));
  }
  // One macro step [0, 0.1] with constant inputs.
  cosim::Signals step(const std::map<std::string, cosim::Signal>& inputs, double t0 = 0) {
    cosim::Polynomials polys;
    for (const auto& [n, sig] : inputs) polys[n] = cosim::InputPolynomial::constant(sig.kind, sig.value);
    const cosim::StepInputs in(cosim::seconds_to_time_point(t0, "t"), cosim::seconds_to_time_point(t0 + 0.1, "t"), polys);
    return model.step(in, false).outputs;
  }
};

std::string raw_outputs(int n) {
  std::string s;
  for (int i = 0; i < n; ++i) s += (i ? ", " : "") + std::string("{name: r") + std::to_string(i) + ", scalar: y" + std::to_string(i) + "}";
  return s;
}

TEST(FmuPorts, KinematicsWithAnglesAndBodyAngularVelocityRoundTrip) {
  const std::string kin_in =
      "{position: [u0, u1, u2], orientation: {angles: [u3, u4, u5], sequence: zyx}, velocity: [u6, u7, u8], "
      "angular_velocity: [u9, u10, u11], angular_velocity_frame: body}";
  const std::string kin_out =
      "{position: [y0, y1, y2], orientation: {angles: [y3, y4, y5], sequence: zyx}, velocity: [y6, y7, y8], "
      "angular_velocity: [y9, y10, y11], angular_velocity_frame: body}";
  Echo e("{inputs: [{name: pose, kinematics: " + kin_in + "}], outputs: [{name: back, kinematics: " + kin_out + "}, " +
         raw_outputs(12) + "]}");
  cosim::Kinematics k;
  k.position = {1, 2, 3};
  // yaw 0.3, pitch -0.2, roll 0.5 (zyx), built independently from axis rotations
  auto axis = [](int a, double angle) {
    cosim::Vec3 v{0, 0, 0};
    v[a] = angle;
    return cosim::quat_exp(v);
  };
  k.orientation = cosim::quat_multiply(cosim::quat_multiply(axis(2, 0.3), axis(1, -0.2)), axis(0, 0.5));
  k.velocity = {0.1, -0.2, 0.3};
  k.angular_velocity = {0.0, 0.0, 1.0};  // ground frame on the bus
  const auto out = e.step({{"pose", {cosim::SignalKind::Kinematics, k.to_value()}}});
  // Raw: the angles and the body-frame angular velocity the FMU was given.
  EXPECT_NEAR(out.at("r3").value[0], 0.3, 1e-12);
  EXPECT_NEAR(out.at("r4").value[0], -0.2, 1e-12);
  EXPECT_NEAR(out.at("r5").value[0], 0.5, 1e-12);
  const cosim::Vec3 w_body = cosim::quat_rotate(cosim::quat_conjugate(k.orientation), k.angular_velocity);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(out.at("r" + std::to_string(9 + i)).value[0], w_body[i], 1e-12);
  EXPECT_GT(std::abs(w_body[0]) + std::abs(w_body[1]), 0.1);  // the frames really differ here
  // Through the output port: the same kinematics again.
  const auto back = cosim::Kinematics::from_value(out.at("back").value);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(back.position[i], k.position[i], 1e-15);
    EXPECT_NEAR(back.velocity[i], k.velocity[i], 1e-15);
    EXPECT_NEAR(back.angular_velocity[i], k.angular_velocity[i], 1e-12);
  }
  const auto rel = cosim::quat_relative(k.orientation, back.orientation);
  EXPECT_LT(std::hypot(rel[0], rel[1], rel[2]), 1e-12);
}

TEST(FmuPorts, QuaternionAndUnusedComponents) {
  Echo e("{inputs: [{name: pose, kinematics: {position: [u0, null, null], orientation: {quaternion: [u1, u2, u3, u4]}}}],"
         " outputs: [{name: back, kinematics: {position: [y0, 5, 0], orientation: {quaternion: [y1, y2, y3, y4]}}}]}");
  cosim::Kinematics k;
  k.position = {1, 2, 3};
  k.orientation = cosim::quat_exp({0.1, 0.2, 0.3});
  const auto back = cosim::Kinematics::from_value(e.step({{"pose", {cosim::SignalKind::Kinematics, k.to_value()}}}).at("back").value);
  EXPECT_EQ(back.position[0], 1);
  EXPECT_EQ(back.position[1], 5);  // a constant in the output mapping
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(back.orientation[i], k.orientation[i], 1e-15);
  // A quaternion that is not unit (a wrong order of components, typically) stops the step.
  Echo bad("{inputs: [{name: a, scalar: u1}], outputs: [{name: back, kinematics: {orientation: {quaternion: [y1, y2, y3, y4]}}}]}", "bad");
  try {
    bad.step({{"a", {cosim::SignalKind::Scalar, {2.0}}}});
    ADD_FAILURE() << "a quaternion of norm 2 was accepted";
  } catch (const fmu::FmuError& x) {
    EXPECT_HAS(x.what(), "output port 'back': the quaternion at t = 0.1 s has norm 2.000000, not 1");
  }
}

// A wrench received about the ground origin, handed to the FMU in the tool's axes about the
// tool's origin, and sent back the other way: equal to the received wrench shifted to the tool.
TEST(FmuPorts, WrenchFrameAndReferencePointBothWays) {
  Echo e("{inputs: [{name: pose, kinematics: {position: [u0, u1, u2], orientation: {quaternion: [u3, u4, u5, u6]}}},"
         "          {name: load, wrench: {force: [u7, u8, u9], torque: [u10, u11, u12], frame: pose, reference_point: pose}}],"
         " outputs: [{name: tool, kinematics: {position: [y0, y1, y2], orientation: {quaternion: [y3, y4, y5, y6]}}},"
         "           {name: back, wrench: {force: [y7, y8, y9], torque: [y10, y11, y12], frame: tool, reference_point: tool}}, " +
         raw_outputs(13) + "]}");
  cosim::Kinematics k;
  k.position = {0, 1, 0};
  k.orientation = cosim::quat_exp({0, 0, M_PI / 2});  // 90 deg about z
  cosim::Wrench w;
  w.force = {1, 0, 0};
  w.torque = {0, 0, 0};
  w.point = {0, 0, 0};
  const auto out = e.step({{"pose", {cosim::SignalKind::Kinematics, k.to_value()}}, {"load", {cosim::SignalKind::Wrench, w.to_value()}}});
  // About (0, 1, 0): t = (r - p) x f = (0, -1, 0) x (1, 0, 0) = (0, 0, 1); in the tool's axes
  // (rotated 90 deg about z) the force (1, 0, 0) is (0, -1, 0).
  const double expect[6] = {0, -1, 0, 0, 0, 1};
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(out.at("r" + std::to_string(7 + i)).value[0], expect[i], 1e-15) << i;
  const auto back = cosim::Wrench::from_value(out.at("back").value);
  const auto shifted = w.shifted_to(k.position);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(back.force[i], shifted.force[i], 1e-15);
    EXPECT_NEAR(back.torque[i], shifted.torque[i], 1e-15);
    EXPECT_NEAR(back.point[i], k.position[i], 1e-15);
  }
}

// Sub-steps: each doStep gets the input polynomial's value at its own start. u(s) = s over the
// macro step [0, 0.1] in 4 sub-steps: u0 = 0, 0.25, 0.5, 0.75 held for 0.025 s each.
TEST(FmuPorts, SubstepsSetTheInputAtEachSubstepStart) {
  Echo e("{substeps: 4, inputs: [{name: u, scalar: u0}], outputs: [{name: y, scalar: y0}, {name: s, scalar: s}]}");
  cosim::InputPolynomial ramp;
  ramp.kind = cosim::SignalKind::Scalar;
  ramp.n_coefficients = 2;
  ramp.coefficients = {0.0, 1.0};
  cosim::Polynomials polys{{"u", ramp}};
  const cosim::StepInputs in(cosim::TimePoint{}, cosim::seconds_to_time_point(0.1, "t"), polys);
  EXPECT_EQ(e.model.inner_step(), cosim::seconds_to_duration(0.025, "h"));
  const auto out = e.model.step(in, false).outputs;
  EXPECT_DOUBLE_EQ(out.at("y").value[0], 0.75);
  EXPECT_NEAR(out.at("s").value[0], 0.025 * (0 + 0.25 + 0.5 + 0.75), 1e-15);
}

TEST(FmuPorts, IntegerAndBooleanInputs) {
  Echo e("{inputs: [{name: n, scalar: n}, {name: b, scalar: b}], outputs: [{name: n_out, scalar: n_out}, {name: b_out, scalar: b_out}]}");
  auto out = e.step({{"n", {cosim::SignalKind::Scalar, {2.6}}}, {"b", {cosim::SignalKind::Scalar, {0.7}}}});
  EXPECT_EQ(out.at("n_out").value[0], 3);  // the nearest integer
  EXPECT_EQ(out.at("b_out").value[0], 1);  // true above 0.5
  out = e.step({{"n", {cosim::SignalKind::Scalar, {-2.4}}}, {"b", {cosim::SignalKind::Scalar, {0.2}}}}, 0.1);
  EXPECT_EQ(out.at("n_out").value[0], -2);
  EXPECT_EQ(out.at("b_out").value[0], 0);
  try {
    e.step({{"n", {cosim::SignalKind::Scalar, {3e9}}}, {"b", {cosim::SignalKind::Scalar, {0}}}}, 0.2);
    ADD_FAILURE() << "3e9 was set into a 32-bit Integer";
  } catch (const cosim::InputError& x) {
    EXPECT_HAS(x.what(), "input 'n': 3000000000.000000 does not fit FMU Integer variable 'n' (32-bit)");
  }
}

// ParticipantCore repeats a step (the master's iterations) through fmi2GetFMUstate and
// fmi2SetFMUstate: a first try with other inputs leaves no trace, the repeat is bit-identical to
// a run that never repeated. The echo FMU integrates s' = u0, so a missing restore would show.
TEST(FmuState, RepeatedStepsOfTheEchoFmuAreBitIdentical) {
  auto run_core = [](bool repeat) {
    fmu::FmuModel m(YAML::Node(YAML::NodeType::Map), "");
    cosim::ParticipantCore core("echo", m);
    cosim::configure_t c{};
    c.protocol_version = cosim::kProtocolVersion;
    c.session_id = 5;
    c.participant = "echo";
    c.t_end_ns = 1'000'000'000;
    c.macro_step_ns = 10'000'000;
    c.parameters_yaml = "{fmu: " + fmutest::pack(fmutest::echo_fmu_entries(), repeat ? "_r.fmu" : "_once.fmu") +
                        ", substeps: 4, inputs: [{name: u, scalar: u0}], outputs: [{name: s, scalar: s}, {name: y, scalar: y0}]}";
    const auto ready = core.configure(c);
    EXPECT_TRUE(ready && ready->ok && ready->can_repeat) << (ready ? ready->error : "");
    std::vector<double> out;
    for (int64_t step = 0; step < 100; ++step) {
      for (int it = 0; it < (repeat ? 3 : 1); ++it) {
        cosim::step_request_t q{};
        q.session_id = 5;
        q.participant = "echo";
        q.step_index = step;
        q.iteration = it;
        q.t_start_ns = step * 10'000'000;
        q.t_end_ns = (step + 1) * 10'000'000;
        const double u = repeat && it < 2 ? 100.0 + it : std::sin(0.1 * step);  // other inputs first
        cosim::Polynomials p{{"u", cosim::InputPolynomial::constant(cosim::SignalKind::Scalar, {u})}};
        q.inputs = cosim::to_message(p);
        const auto r = core.handle(q);
        if (!r || r->status != cosim::step_reply_t::OK) {
          ADD_FAILURE() << (r ? r->message : "no reply");
          return out;
        }
        if (it == (repeat ? 2 : 0))
          for (const auto& sc : r->outputs.scalars) out.push_back(sc.value);
      }
    }
    return out;
  };
  const auto once = run_core(false), thrice = run_core(true);
  ASSERT_EQ(once.size(), 200u);
  EXPECT_EQ(std::memcmp(once.data(), thrice.data(), once.size() * sizeof(double)), 0);
  EXPECT_NE(once[198], 0.0);  // s integrated something
}

// ---------------------------------------------------------------------------------------------
// The command line: a config with a relative fmu path, MODEL.fmu --mapping, problems found at
// start (exit 2, the file named), and the unpacked folder gone after every exit.

TEST(FmuCommandLine, ChecksTheFmuAtStartAndCleansUp) {
  namespace fs = std::filesystem;
  const fs::path dir = fmutest::temp_path("_dir");
  fs::remove_all(dir);
  fs::create_directories(dir / "tmp");
  fmutest::write_zip((dir / "echo.fmu").string(), fmutest::echo_fmu_entries());
  std::ofstream(dir / "good.yaml") << "fmu: echo.fmu\noutputs: [{name: y, scalar: y0}]\n";
  std::ofstream(dir / "bad.yaml") << "fmu: echo.fmu\noutputs: [{name: y, scalar: y99}]\n";
  std::ofstream(dir / "map.yaml") << "outputs: [{name: y, scalar: y0}]\n";
  setenv("TMPDIR", (dir / "tmp").c_str(), 1);  // the children unpack here
  const std::string url = harness::bus_url();
  const std::string adapter = harness::bin("fmu_adapter");
  auto run_adapter = [&](std::vector<std::string> args, const std::string& log) {
    args.insert(args.begin(), adapter);
    auto p = harness::spawn(args, (dir / log).string());
    return harness::wait_for(p, 30);
  };
  // Good: loads, then waits for a master that does not come (exit 3 after --wait).
  EXPECT_EQ(run_adapter({(dir / "good.yaml").string(), "--wait", "0.5", "--bus", url}, "good.log"), 3)
      << harness::read_text((dir / "good.log").string());
  EXPECT_EQ(run_adapter({(dir / "echo.fmu").string(), "--mapping", (dir / "map.yaml").string(), "--wait", "0.5", "--bus", url},
                        "map.log"),
            3)
      << harness::read_text((dir / "map.log").string());
  EXPECT_EQ(run_adapter({(dir / "bad.yaml").string(), "--bus", url}, "bad.log"), 2);
  const std::string bad = harness::read_text((dir / "bad.log").string());
  EXPECT_HAS(bad, "fmu_adapter: config error in " + (dir / "bad.yaml").string() +
                      ": outputs.0.scalar: FMU echo.fmu (model 'EchoFmu') has no variable 'y99'");
  EXPECT_EQ(run_adapter({(dir / "missing.fmu").string(), "--mapping", (dir / "map.yaml").string(), "--bus", url}, "missing.log"), 2);
  EXPECT_HAS(harness::read_text((dir / "missing.log").string()), "missing.fmu': file not found");
  EXPECT_EQ(run_adapter({(dir / "echo.fmu").string(), "--mapping", (dir / "map.yaml").string(), "--set", "fmu=x.fmu", "--bus", url},
                        "twice.log"),
            2);
  EXPECT_HAS(harness::read_text((dir / "twice.log").string()), "the FMU is given twice");
  unsetenv("TMPDIR");
  EXPECT_TRUE(fs::is_empty(dir / "tmp")) << "an unpacked FMU folder was left behind";
}

// ---------------------------------------------------------------------------------------------
// Through cosim_master over LCM.

std::string config(const std::string& name) { return "tests/fmu/" + name; }

// Runs the master on a config of tests/fmu with the CSV written; returns the exit code.
// The adapters it launches unpack into a folder of their own, which must be empty afterwards
// (also after refusals and failures).
int run(const std::string& cfg, std::vector<std::string> overrides, const std::string& csv, double timeout = 90) {
  namespace fs = std::filesystem;
  overrides.push_back("output.csv=" + csv);
  const fs::path tmp = csv + ".tmp";
  fs::remove_all(tmp);
  fs::create_directories(tmp);
  setenv("TMPDIR", tmp.c_str(), 1);
  const int code = harness::run_master(overrides, csv + ".h5", timeout, config(cfg));
  unsetenv("TMPDIR");
  for (int i = 0; i < 100 && !fs::is_empty(tmp); ++i)  // the launcher may not wait for every child
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_TRUE(fs::is_empty(tmp)) << "an unpacked FMU folder was left in " << tmp;
  return code;
}

// Our run against a reference CSV: same times, every column within tol (absolute).
void compare(const fmutest::Table& ours, const fmutest::Table& ref, const std::string& prefix,
             const std::vector<std::pair<std::string, std::string>>& columns, double tol) {
  ASSERT_EQ(ours.rows.size(), ref.rows.size());
  double worst = 0;
  for (std::size_t i = 0; i < ours.rows.size(); ++i) {
    ASSERT_NEAR(ours.number(i, "time"), ref.number(i, "time"), 1e-9) << i;
    for (const auto& [mine, theirs] : columns) {
      const double a = ours.number(i, prefix + mine), b = ref.number(i, theirs);
      worst = std::max(worst, std::abs(a - b));
      ASSERT_NEAR(a, b, tol) << "row " << i << " t = " << ours.number(i, "time") << " column " << theirs;
    }
  }
  std::cerr << "largest difference from the reference: " << worst << "\n";
}

// Tolerance for the three ODE FMUs: the reference CSVs come from the same binaries (the
// Reference FMUs' fixed-step forward Euler inside doStep) with one doStep per output interval,
// which is what the adapter does at macro step = the CSV's interval. The arithmetic is the same;
// only the time arguments of doStep may differ in the last bit (ours come from integer
// nanoseconds, the reference tool adds up the step). 1e-9 leaves room for that and nothing
// else: one doStep of the wrong length, a shifted row or a wrong start value is off by 1e-4 or
// more (checked below with the step doubled).
constexpr double kOdeTolerance = 1e-9;

TEST(FmuReference, BouncingBallMatchesItsReferenceOverLcm) {
  REQUIRE_REFERENCE_FMUS();
  const std::string csv = fmutest::temp_path(".csv");
  const std::string fmu = fmutest::fmus_dir() + "/BouncingBall.fmu";
  ASSERT_EQ(run("bouncing_ball.yaml", {"participants.ball.parameters.fmu=" + fmu}, csv), 0) << harness::read_text(csv + ".h5.log");
  const auto ref = fmutest::read_csv(fmutest::fmus_dir() + "/BouncingBall_out.csv");
  compare(fmutest::read_csv(csv), ref, "ball.", {{"h", "h"}, {"v", "v"}}, kOdeTolerance);
  // Ten doSteps of 1 ms per macro step (the FMU's own solver step): the same trajectory.
  const std::string sub = fmutest::temp_path("_sub.csv");
  ASSERT_EQ(run("bouncing_ball.yaml", {"participants.ball.parameters.fmu=" + fmu, "participants.ball.parameters.substeps=10"}, sub), 0)
      << harness::read_text(sub + ".h5.log");
  compare(fmutest::read_csv(sub), ref, "ball.", {{"h", "h"}, {"v", "v"}}, kOdeTolerance);
  // The tolerance catches a wrong mapping: start value e changed, or h read as v.
  const std::string e = fmutest::temp_path("_e.csv");
  ASSERT_EQ(run("bouncing_ball.yaml", {"participants.ball.parameters.fmu=" + fmu, "participants.ball.parameters.start={e: 0.8, h: 1.5}"}, e), 0)
      << harness::read_text(e + ".h5.log");
  const auto changed = fmutest::read_csv(e);
  EXPECT_EQ(changed.number(0, "ball.h"), 1.5);  // the start value reached the FMU
  double diff = 0;
  for (std::size_t i = 0; i < changed.rows.size(); ++i) diff = std::max(diff, std::abs(changed.number(i, "ball.h") - ref.number(i, "h")));
  EXPECT_GT(diff, 0.1);
}

TEST(FmuReference, DahlquistMatchesItsReferenceOverLcm) {
  REQUIRE_REFERENCE_FMUS();
  const std::string csv = fmutest::temp_path(".csv");
  const std::string fmu = fmutest::fmus_dir() + "/Dahlquist.fmu";
  ASSERT_EQ(run("dahlquist.yaml", {"participants.dahlquist.parameters.fmu=" + fmu}, csv), 0) << harness::read_text(csv + ".h5.log");
  compare(fmutest::read_csv(csv), fmutest::read_csv(fmutest::fmus_dir() + "/Dahlquist_out.csv"), "dahlquist.", {{"x", "x"}}, kOdeTolerance);
  // The parameter k from the mapping reaches the FMU: k = 1.01 gives x(0.1) = 1 - 0.101 (forward
  // Euler), 1e-3 away from the reference: the tolerance above would catch it.
  const std::string k = fmutest::temp_path("_k.csv");
  ASSERT_EQ(run("dahlquist.yaml", {"participants.dahlquist.parameters.fmu=" + fmu, "participants.dahlquist.parameters.start={k: 1.01}"}, k), 0)
      << harness::read_text(k + ".h5.log");
  EXPECT_NEAR(fmutest::read_csv(k).number(1, "dahlquist.x"), 0.899, 1e-12);
}

TEST(FmuReference, VanDerPolMatchesItsReferenceOverLcm) {
  REQUIRE_REFERENCE_FMUS();
  const std::string csv = fmutest::temp_path(".csv");
  ASSERT_EQ(run("van_der_pol.yaml", {"participants.vdp.parameters.fmu=" + fmutest::fmus_dir() + "/VanDerPol.fmu"}, csv), 0)
      << harness::read_text(csv + ".h5.log");
  compare(fmutest::read_csv(csv), fmutest::read_csv(fmutest::fmus_dir() + "/VanDerPol_out.csv"), "vdp.",
          {{"x0", "x0"}, {"x1", "x1"}}, kOdeTolerance);
}

// Feedthrough alone, inputs at their start values: the reference CSV (the default experiment,
// which applied no input: every output 0, Boolean false, Enumeration 1). A copy does no
// arithmetic, so the tolerance is 0.
TEST(FmuReference, FeedthroughAloneMatchesItsReferenceOverLcm) {
  REQUIRE_REFERENCE_FMUS();
  const std::string csv = fmutest::temp_path(".csv");
  ASSERT_EQ(run("feedthrough_alone.yaml", {"participants.ft.parameters.fmu=" + fmutest::fmus_dir() + "/Feedthrough.fmu"}, csv), 0)
      << harness::read_text(csv + ".h5.log");
  const auto ref = fmutest::read_csv(fmutest::fmus_dir() + "/Feedthrough_out.csv");
  const auto ours = fmutest::read_csv(csv);
  compare(ours, ref, "ft.",
          {{"float64_continuous", "Float64_continuous_output"}, {"float64_discrete", "Float64_discrete_output"},
           {"int32", "Int32_output"}, {"enumeration", "Enumeration_output"}},
          0.0);
  for (std::size_t i = 0; i < ours.rows.size(); ++i)
    EXPECT_EQ(ours.number(i, "ft.boolean"), ref.rows[i][ref.column("Boolean_output")] == "true" ? 1.0 : 0.0) << i;
}

// Feedthrough with its input CSV played by prescribed_participant: Int32_input (the one column of
// Feedthrough_in.csv that FMI 2.0's Feedthrough has) becomes the motion's x, x / 2^31 its y. The
// master holds each input over the step (order 0), the FMU copies it: the output at t_{i+1} is
// the input at t_i, exactly (Int32: the nearest integer of the linearly interpolated value).
// The FMU's wrench output (force x = Float64_continuous_output) reaches the prescribed
// participant's record.
TEST(FmuReference, FeedthroughFollowsItsInputCsvPlayedByPrescribedParticipant) {
  REQUIRE_REFERENCE_FMUS();
  const auto in = fmutest::read_csv(fmutest::fmus_dir() + "/Feedthrough_in.csv");
  const std::string motion = fmutest::temp_path("_motion.csv");
  {
    std::ofstream m(motion);
    m << "time,x,y,z,qw,qx,qy,qz\n";
    for (std::size_t i = 0; i < in.rows.size(); ++i) {
      const double x = in.number(i, "Int32_input");
      char line[160];
      std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g,0,1,0,0,0\n", in.number(i, "time"), x, x / 2147483648.0);
      m << line;
    }
  }
  const std::string csv = fmutest::temp_path(".csv"), record = fmutest::temp_path("_record.csv");
  ASSERT_EQ(run("feedthrough.yaml",
                {"participants.ft.parameters.fmu=" + fmutest::fmus_dir() + "/Feedthrough.fmu",
                 "participants.source.parameters.tools.0.csv=" + motion, "participants.source.parameters.record=" + record},
                csv),
            0)
      << harness::read_text(csv + ".h5.log");
  const auto ours = fmutest::read_csv(csv);
  ASSERT_EQ(ours.rows.size(), 21u);
  auto input_at = [&](double t) {  // the CSV's Int32_input, linear between rows, held after
    const double t0 = in.number(0, "time"), t1 = in.number(1, "time");
    const double x0 = in.number(0, "Int32_input"), x1 = in.number(1, "Int32_input");
    if (t >= t1) return x1;
    return x0 + (x1 - x0) * (t - t0) / (t1 - t0);
  };
  EXPECT_EQ(ours.number(0, "ft.int32"), 0);  // start value, before any input
  for (std::size_t i = 1; i < ours.rows.size(); ++i) {
    const double t_prev = ours.number(i - 1, "time");
    const double x = input_at(t_prev);
    EXPECT_NEAR(ours.number(i, "ft.int32"), std::nearbyint(x), 1.0) << i;  // interpolation rounding
    EXPECT_NEAR(ours.number(i, "ft.float64_continuous"), x / 2147483648.0, 1e-9) << i;
    EXPECT_EQ(ours.number(i, "ft.echo.fx"), ours.number(i, "ft.float64_continuous")) << i;
  }
  EXPECT_EQ(ours.number(1, "ft.int32"), -2147483648.0);  // the CSV's first value, exactly
  EXPECT_EQ(ours.number(20, "ft.int32"), 2147483647.0);  // its last
  const auto rec = fmutest::read_csv(record);
  ASSERT_GE(rec.rows.size(), 19u);
  for (std::size_t i = 1; i < rec.rows.size(); ++i)  // the wrench received at the step's start
    EXPECT_EQ(rec.number(i, "fx"), ours.number(i, "ft.echo.fx")) << i;
}

// canGetAndSetFMUstate="false": the master refuses start-up iterations before the first step
// and says which FMU and what to change; with startup_iterations: 0 the same FMU runs. The echo
// FMU repacked, so the test runs without the Reference FMUs.
TEST(FmuState, FmuWithoutStateIsRefusedForStartupIterationsOverLcm) {
  Entries e = fmutest::echo_fmu_entries();
  std::string& xml = fmutest::entry(e, "modelDescription.xml");
  const std::string before = xml;
  xml = fmutest::replace_all(xml, "canGetAndSetFMUstate=\"true\"", "canGetAndSetFMUstate=\"false\"");
  ASSERT_NE(xml, before);
  const std::string fmu = fmutest::pack(e, "_nostate.fmu");
  const std::string motion = fmutest::temp_path("_motion.csv");
  std::ofstream(motion) << "time,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n1,1,0,0,1,0,0,0\n";
  const std::vector<std::string> base{"participants.fmu.parameters.fmu=" + fmu, "participants.source.parameters.tools.0.csv=" + motion,
                                      "predictors.hold.order=1", "startup_iterations=2"};
  const std::string csv = fmutest::temp_path(".csv");
  ASSERT_EQ(run("echo.yaml", base, csv), 2);
  const std::string log = harness::read_text(csv + ".h5.log");
  EXPECT_HAS(log, "cosim_master: config refused: startup_iterations: 2 (with predictor order 1) redoes the first steps, "
                  "but participant 'fmu' cannot repeat a step (FMU FmuState_FmuWithoutStateIsRefusedForStartupIterationsOverLcm_nostate.fmu "
                  "(model 'EchoFmu') declares canGetAndSetFMUstate=\"false\"");
  EXPECT_HAS(log, "set startup_iterations: 0");
  auto no_iterations = base;
  no_iterations.push_back("startup_iterations=0");
  const std::string ok = fmutest::temp_path("_ok.csv");
  EXPECT_EQ(run("echo.yaml", no_iterations, ok), 0) << harness::read_text(ok + ".h5.log");
  // The good echo FMU does the iterations: the first step is done 3 times, the record says so.
  const std::string good = fmutest::temp_path("_good.csv");
  ASSERT_EQ(run("echo.yaml", {"participants.fmu.parameters.fmu=" + fmutest::pack(fmutest::echo_fmu_entries(), "_good.fmu"),
                              "participants.source.parameters.tools.0.csv=" + motion, "predictors.hold.order=1", "startup_iterations=2"},
                good),
            0)
      << harness::read_text(good + ".h5.log");
  const auto iterations = harness::read_dataset(good + ".h5", "timing/iterations");
  ASSERT_EQ(iterations.size(), 6u);  // the initial row, then 5 steps
  EXPECT_EQ(iterations[1], 3);
  EXPECT_EQ(iterations[2], 1);
  // Order 1 through the iterations: the echoed x follows the ramp x = t one step late, exactly
  // from the second step on (interpolation through the new sample on the first).
  const auto table = fmutest::read_csv(good);
  ASSERT_EQ(table.rows.size(), 6u);
  for (std::size_t i = 1; i < table.rows.size(); ++i)
    EXPECT_NEAR(table.number(i, "fmu.echo.fx"), table.number(i - 1, "time"), 1e-12) << i;
}

// A repeated step restores the FMU state: VanDerPol stepped with every step done three times
// (through ParticipantCore, as the master's iterations do) gives the same bits as a run that
// never repeats, and as the reference run over LCM.
TEST(FmuState, RepeatedStepsAreBitIdenticalThroughTheFmuState) {
  REQUIRE_REFERENCE_FMUS();
  auto run_core = [](int iterations) {
    fmu::FmuModel m(YAML::Node(YAML::NodeType::Map), "");
    cosim::ParticipantCore core("vdp", m);
    core.set_identity(7, "host", 1);
    cosim::configure_t c{};
    c.protocol_version = cosim::kProtocolVersion;
    c.session_id = 99;
    c.participant = "vdp";
    c.t_start_ns = 0;
    c.t_end_ns = 2'000'000'000;
    c.macro_step_ns = 10'000'000;
    c.parameters_yaml = "{fmu: " + fmutest::fmus_dir() + "/VanDerPol.fmu, outputs: [{name: x0, scalar: x0}, {name: x1, scalar: x1}]}";
    const auto ready = core.configure(c);
    EXPECT_TRUE(ready && ready->ok) << (ready ? ready->error : "");
    EXPECT_TRUE(ready->can_repeat);
    std::vector<double> out;
    for (int64_t step = 0; step < 200; ++step) {
      std::vector<double> first;
      for (int it = 0; it < iterations; ++it) {
        cosim::step_request_t q{};
        q.session_id = 99;
        q.participant = "vdp";
        q.step_index = step;
        q.iteration = it;
        q.t_start_ns = step * 10'000'000;
        q.t_end_ns = (step + 1) * 10'000'000;
        const auto r = core.handle(q);
        if (!r || r->status != cosim::step_reply_t::OK) {
          ADD_FAILURE() << (r ? r->message : "no reply");
          return out;
        }
        const std::vector<double> v{r->outputs.scalars[0].value, r->outputs.scalars[1].value};
        if (it == 0) first = v;
        else EXPECT_EQ(std::memcmp(v.data(), first.data(), sizeof(double) * 2), 0) << step << " " << it;
      }
      out.insert(out.end(), first.begin(), first.end());
    }
    return out;
  };
  const auto once = run_core(1), thrice = run_core(3);
  ASSERT_EQ(once.size(), 400u);
  EXPECT_EQ(std::memcmp(once.data(), thrice.data(), once.size() * sizeof(double)), 0);
  // and they are the reference trajectory
  const auto ref = fmutest::read_csv(fmutest::fmus_dir() + "/VanDerPol_out.csv");
  for (std::size_t i = 0; i < 200; ++i) EXPECT_NEAR(thrice[2 * i], ref.number(i + 1, "x0"), kOdeTolerance) << i;
}

// A broken FMU and an FMU failing mid-run, launched by the master: named errors, exit codes 2
// and 1, nothing hangs, the steps before the failure are kept.
TEST(FmuBroken, RunsStopWithTheFmuNamedOverLcm) {
  Entries e = fmutest::fail_fmu_entries();
  e.pop_back();
  const std::string nobin = fmutest::pack(e, "_nobin.fmu");
  const std::string csv = fmutest::temp_path(".csv");
  const cosim::Stopwatch wall;
  ASSERT_EQ(run("fail_fmu.yaml", {"participants.failing.parameters.fmu=" + nobin}, csv), 2);
  std::string log = harness::read_text(csv + ".h5.log");
  EXPECT_HAS(log, "cosim_master: config refused: participants.failing.parameters: FMU 'FmuBroken_RunsStopWithTheFmuNamedOverLcm_nobin.fmu (model 'FailFmu')'");
  EXPECT_HAS(log, "no binary for this platform");

  const std::string good = fmutest::pack(fmutest::fail_fmu_entries(), "_good.fmu");
  const std::string csv2 = fmutest::temp_path("_midrun.csv");
  ASSERT_EQ(run("fail_fmu.yaml", {"participants.failing.parameters.fmu=" + good}, csv2), 1);
  log = harness::read_text(csv2 + ".h5.log");
  EXPECT_HAS(log, "cosim_master: run failed: participant 'failing' step 5 (t = 0.500000 s) failed: FMU 'FmuBroken_RunsStopWithTheFmuNamedOverLcm_good.fmu (model 'FailFmu')' "
                  "(instance 'failing'): fmi2DoStep at t = 0.5 s (step 0.1 s) returned fmi2Error");
  EXPECT_HAS(log, "deliberate failure");
  // the FMU's own message also went to the log as it happened, with its name
  EXPECT_HAS(log, "fmu_adapter failing: FMU 'FmuBroken_RunsStopWithTheFmuNamedOverLcm_good.fmu (model 'FailFmu')' (instance 'failing') [fmi2Error, logStatusError]: deliberate failure");
  EXPECT_EQ(harness::read_dataset(csv2 + ".h5", "participants/failing/outputs/x").size(), 6u);  // t = 0 .. 0.5
  EXPECT_LT(wall.seconds(), 60.0);
}

}  // namespace
