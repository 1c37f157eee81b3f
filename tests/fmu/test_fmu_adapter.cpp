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
#include "ssp_import.hpp"

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
  EXPECT_HAS(msg, "no instantiationToken attribute (required by FMI 3.0)");  // read as 3.0
  msg = with_xml("fmiVersion=\"2.0\"", "fmiVersion=\"4.0\"", "_fmi4.fmu");
  EXPECT_HAS(msg, "fmiVersion is \"4.0\"; fmu_adapter imports FMI 2.0 and 3.0");
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

// Feedthrough with its input CSV played by prescribed_adapter: Int32_input (the one column of
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


// ---------------------------------------------------------------------------------------------
// FMI 2.0 fixes (issue 47): an FMU that ends itself, a resource folder with a space and a '%',
// start values of the wrong type found at start, a modelIdentifier that names no binary.

// The counter FMU reaches stop_at inside a doStep: fmi2Discard with fmi2Terminated. The step
// ends at the time the FMU reached, with its outputs there, and says so; no further step.
TEST(FmuEnds, TheStepEndsWhereTheFmuEndedItself) {
  fmu::FmuModel m(YAML::Node(YAML::NodeType::Map), "");
  YAML::Node p = yaml("{instance: c, substeps: 4, start: {stop_at: 0.35}, outputs: [{name: count, scalar: count}]}");
  p["fmu"] = fmutest::pack(fmutest::counter_fmu_entries("2.5"));
  m.configure(p, run_info(1.0, 0.2));
  cosim::Polynomials none;
  auto r = m.step(cosim::StepInputs(cosim::TimePoint{}, cosim::seconds_to_time_point(0.2, "t"), none), false);
  EXPECT_FALSE(r.ended_at);
  EXPECT_NEAR(r.outputs.at("count").value[0], 0.5, 1e-15);
  // Sub-steps of 0.05 s: [0.3, 0.35] completes, [0.35, 0.4] passes stop_at = 0.35 and ends.
  r = m.step(cosim::StepInputs(cosim::seconds_to_time_point(0.2, "t"), cosim::seconds_to_time_point(0.4, "t"), none), false);
  ASSERT_TRUE(r.ended_at);
  EXPECT_EQ(*r.ended_at, cosim::seconds_to_time_point(0.35, "t"));
  EXPECT_NEAR(r.outputs.at("count").value[0], 2.5 * 0.35, 1e-14);  // the outputs where it ended
  EXPECT_HAS(r.ended_reason, "(instance 'c') ended itself: fmi2DoStep at t = 0.35 s (step 0.05 s) returned fmi2Discard "
                             "with fmi2Terminated: the FMU ended the simulation at its last successful time 0.35 s");
  EXPECT_THROW(m.step(cosim::StepInputs(cosim::seconds_to_time_point(0.4, "t"), cosim::seconds_to_time_point(0.6, "t"), none), false),
               fmu::FmuError);
  // A discard without fmi2Terminated is a failure that says what the FMU did and did not say.
  fmu::FmuModel d(YAML::Node(YAML::NodeType::Map), "");
  YAML::Node q = yaml("{start: {stop_at: 0.15, terminate: false}, outputs: [{name: count, scalar: count}]}");
  q["fmu"] = fmutest::pack(fmutest::counter_fmu_entries(), "_discard.fmu");
  d.configure(q, run_info(1.0, 0.2));
  try {
    d.step(cosim::StepInputs(cosim::TimePoint{}, cosim::seconds_to_time_point(0.2, "t"), none), false);
    ADD_FAILURE() << "a plain discard was accepted";
  } catch (const fmu::FmuError& e) {
    EXPECT_HAS(e.what(), "fmi2DoStep at t = 0 s (step 0.2 s) returned fmi2Discard: the FMU could not complete the step and "
                         "did not ask to end the simulation (fmi2GetBooleanStatus(fmi2Terminated) is false)");
  }
}

// Under cosim_master over LCM: the counter ends itself at t = 9 s of a 10 s run (the doStep
// from 9 s is refused at once: ended at the step's start) and at 9.05 s (inside a step). The
// run ends cleanly (exit 0, /status finished, /ended says why), recorded up to 9 s, the count
// exact there; without fmi2Terminated it is a failed run (exit 1) with the reason.
TEST(FmuEnds, AnFmuThatEndsItselfEndsTheRunCleanlyOverLcm) {
  const std::string fmu = fmutest::pack(fmutest::counter_fmu_entries("2.5"));
  for (const std::string stop : {"9", "9.05"}) {
    const std::string csv = fmutest::temp_path("_" + stop + ".csv");
    ASSERT_EQ(run("counter.yaml", {"participants.counter.parameters.fmu=" + fmu,
                                   "participants.counter.parameters.start.stop_at=" + stop}, csv), 0)
        << harness::read_text(csv + ".h5.log");
    const std::string log = harness::read_text(csv + ".h5.log");
    EXPECT_HAS(log, "cosim_master: participant 'counter' ended the run at t = " + stop + " s: FMU '");
    EXPECT_HAS(log, "(instance 'counter') ended itself: fmi2DoStep at t = 9 s (step 0.1 s) returned fmi2Discard with "
                    "fmi2Terminated: the FMU ended the simulation at its last successful time " + stop + " s; recorded up to t = 9 s");
    const auto t = fmutest::read_csv(csv);
    ASSERT_EQ(t.rows.size(), 91u) << stop;  // t = 0, 0.1, ..., 9
    EXPECT_NEAR(t.number(90, "time"), 9.0, 1e-12);
    EXPECT_NEAR(t.number(90, "counter.count"), 22.5, 1e-12);
    EXPECT_EQ(harness::read_dataset(csv + ".h5", "time").size(), 91u);
    EXPECT_EQ(harness::read_string(csv + ".h5", "status"), "finished");
    EXPECT_HAS(harness::read_string(csv + ".h5", "ended"), "participant 'counter' ended the run at t = " + stop + " s");
  }
  const std::string csv = fmutest::temp_path("_discard.csv");
  ASSERT_EQ(run("counter.yaml", {"participants.counter.parameters.fmu=" + fmu, "participants.counter.parameters.start.terminate=false"}, csv), 1);
  EXPECT_HAS(harness::read_text(csv + ".h5.log"), "returned fmi2Discard: the FMU could not complete the step and did not ask to end the simulation");
}

TEST(FmuResources, TheResourceLocationIsAPercentEncodedFileUri) {
  EXPECT_EQ(fmu::file_uri("/tmp/a b%c/resources/"), "file:///tmp/a%20b%25c/resources/");
  EXPECT_EQ(fmu::file_uri("/x/Ab-9._~/"), "file:///x/Ab-9._~/");
  EXPECT_EQ(fmu::file_uri("/\xc3\xa4#?"), "file:///%C3%A4%23%3F");
  // The counter FMU decodes the URI and reads resources/rate.txt; unpacked below a folder whose
  // name has a space and a '%' (and "%41", which a decoder would turn into "A" if it were not
  // encoded), it must find it.
  namespace fs = std::filesystem;
  const fs::path odd = fmutest::temp_path("_dir with space%41%");
  fs::remove_all(odd);
  fs::create_directories(odd);
  setenv("TMPDIR", odd.c_str(), 1);
  {
    fmu::FmuModel m(YAML::Node(YAML::NodeType::Map), "");
    YAML::Node p = yaml("{outputs: [{name: count, scalar: count}, {name: rate, scalar: rate_out}]}");
    p["fmu"] = fmutest::pack(fmutest::counter_fmu_entries("4.25"));
    try {
      m.configure(p, run_info(1.0, 0.5));
      const auto r = m.step(cosim::StepInputs(cosim::TimePoint{}, cosim::seconds_to_time_point(0.5, "t"), cosim::Polynomials{}), false);
      EXPECT_EQ(r.outputs.at("rate").value[0], 4.25);
      EXPECT_EQ(r.outputs.at("count").value[0], 4.25 * 0.5);
    } catch (const std::exception& e) {
      ADD_FAILURE() << e.what();
    }
  }
  unsetenv("TMPDIR");
  EXPECT_TRUE(fs::is_empty(odd));
}

// A start value of the wrong type is refused when the adapter starts with the FMU and the
// mapping, without a master (exit 2 at once, not 3 after waiting for one).
TEST(FmuCommandLine, AStartValueOfTheWrongTypeIsRefusedAtStart) {
  namespace fs = std::filesystem;
  const fs::path dir = fmutest::temp_path("_dir");
  fs::remove_all(dir);
  fs::create_directories(dir);
  fmutest::write_zip((dir / "echo.fmu").string(), fmutest::echo_fmu_entries());
  std::ofstream(dir / "int.yaml") << "start: {n: 2.5}\noutputs: [{name: y, scalar: y0}]\n";
  std::ofstream(dir / "bool.yaml") << "start: {b: 1.5}\noutputs: [{name: y, scalar: y0}]\n";
  std::ofstream(dir / "real.yaml") << "start: {u0: yes please}\noutputs: [{name: y, scalar: y0}]\n";
  const std::string url = harness::bus_url();
  for (const auto& [file, expect] : std::vector<std::pair<std::string, std::string>>{
           {"int.yaml", "start.n: 'n' is an FMI Integer variable; expected an integer, got '2.5'"},
           {"bool.yaml", "start.b: 'b' is an FMI Boolean variable; expected true or false, got '1.5'"},
           {"real.yaml", "start.u0: 'u0' is an FMI Real variable; expected a finite number, got 'yes please'"}}) {
    auto p = harness::spawn({harness::bin("fmu_adapter"), (dir / "echo.fmu").string(), "--mapping", (dir / file).string(),
                             "--wait", "20", "--bus", url},
                            (dir / (file + ".log")).string());
    EXPECT_EQ(harness::wait_for(p, 15), 2) << file;
    const std::string log = harness::read_text((dir / (file + ".log")).string());
    EXPECT_HAS(log, "fmu_adapter: config error in " + (dir / file).string() + ": " + expect);
  }
}

// binaries/linux64/ holds a library, but not the one the modelIdentifier names: the message
// says so (not "no binary for this platform ... it has binaries for: linux64").
TEST(FmuBroken, AModelIdentifierThatNamesNoBinaryIsNamed) {
  Entries e = fmutest::fail_fmu_entries();
  e.back().first = "binaries/linux64/FailFmu.so";
  const std::string msg = configure_error(fmutest::pack(e, "_renamed.fmu"));
  EXPECT_HAS(msg, "<CoSimulation modelIdentifier=\"fail_fmu\"> in modelDescription.xml names the binary "
                  "binaries/linux64/fail_fmu.so, which is not in the archive; binaries/linux64/ holds FailFmu.so");
  EXPECT_HAS(msg, "repack it with the binary named fail_fmu.so");
  EXPECT_EQ(msg.find("no binary for this platform"), std::string::npos) << msg;
}

// --resume with an FMU (canSerializeFMUstate): the counter run by a hand-started fmu_adapter is
// killed (kill -9) after a checkpoint; a new fmu_adapter and cosim_master --resume finish the
// run, and the record and the CSV equal an uninterrupted run's bit for bit. The counter's state
// (its time and count) comes back from the serialized FMU state: a fresh instance would refuse
// the first step (it is at t = 0) and count from 0.
// One participant `name` from `cfg` started by hand (fmu_adapter with everything from the
// master's parameters), 20000 steps with a checkpoint every 100; killed (kill -9) after the
// checkpoint after 3000 steps, resumed with a new fmu_adapter: returns the datasets `outputs`
// of the uninterrupted and the resumed record, and checks the CSV and /status.
std::vector<std::pair<std::vector<double>, std::vector<double>>> kill_and_resume(
    const std::string& cfg, const std::string& name, const std::vector<std::string>& sets, const std::vector<std::string>& outputs) {
  namespace fs = std::filesystem;
  std::vector<std::pair<std::vector<double>, std::vector<double>>> out;
  const std::string url = harness::bus_url();
  const std::string full = fmutest::temp_path("_full.h5"), h5 = fmutest::temp_path(".h5");
  fs::remove_all(h5 + ".checkpoints");
  auto master_args = [&](const std::string& file) {
    std::vector<std::string> a{harness::bin("cosim_master"), harness::source(config(cfg)), "--output", file, "--csv", file + ".csv",
                               "--set", "bus.url=" + url, "--set", "participants." + name + ".launch=null",
                               "--set", "participants." + name + ".timeout=0.5", "--set", "output.progress=off",
                               // started by hand without a key: unkeyed by choice
                               "--set", "bus.authenticate=false"};
    for (const auto& s : sets) a.insert(a.end(), {"--set", s});
    return a;
  };
  auto adapter = [&](const std::string& log) {
    return harness::spawn({harness::bin("fmu_adapter"), "--name", name, "--bus", url, "--wait", "60"}, log);
  };
  {
    auto a = adapter(full + ".adapter.log");
    auto m = harness::spawn(master_args(full), full + ".log");
    EXPECT_EQ(harness::wait_for(m, 180), 0) << harness::read_text(full + ".log");
    EXPECT_EQ(harness::wait_for(a, 10), 0);
  }
  auto a = adapter(h5 + ".adapter.log");
  auto m = harness::spawn(master_args(h5), h5 + ".log");
  const std::string folder = h5 + ".checkpoints";
  bool checkpointed = false;
  for (int i = 0; i < 60000 && !checkpointed; ++i) {
    std::error_code ec;
    for (const auto& f : fs::directory_iterator(folder, ec)) {
      const std::string file = f.path().filename().string();
      const auto us = file.rfind('_');
      if (file.size() > 5 && file.substr(file.size() - 5) == ".ckpt" && us != std::string::npos && std::stoll(file.substr(us + 1)) >= 3000)
        checkpointed = true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_TRUE(checkpointed) << harness::read_text(h5 + ".log");
  kill(a.pid, SIGKILL);
  harness::wait_for(a, 5);
  EXPECT_EQ(harness::wait_for(m, 30), 1) << harness::read_text(h5 + ".log");
  const std::size_t rows = harness::read_dataset(h5, "time").size();
  EXPECT_LT(rows, 20001u) << "the run was not interrupted";
  const double at = harness::read_dataset(h5, "checkpoint/steps_done").at(0);
  EXPECT_GE(at, 2900);
  std::printf("fmu_adapter killed after %zu of 20000 steps; resuming after %.0f\n", rows - 1, at);
  auto b = adapter(h5 + ".adapter2.log");
  auto r = harness::spawn({harness::bin("cosim_master"), "--resume", h5}, h5 + ".resume.log");
  EXPECT_EQ(harness::wait_for(r, 180), 0) << harness::read_text(h5 + ".resume.log") << harness::read_text(h5 + ".adapter2.log");
  EXPECT_EQ(harness::wait_for(b, 10), 0);
  for (const auto& d : outputs)
    out.push_back({harness::read_dataset(full, "participants/" + name + "/outputs/" + d), harness::read_dataset(h5, "participants/" + name + "/outputs/" + d)});
  EXPECT_EQ(harness::read_dataset(h5, "time"), harness::read_dataset(full, "time"));
  EXPECT_TRUE(harness::read_text(h5 + ".csv") == harness::read_text(full + ".csv")) << "the resumed CSV differs";
  EXPECT_EQ(harness::read_string(h5, "status"), "finished");
  EXPECT_FALSE(fs::exists(folder)) << "the finished run's checkpoints were not deleted";
  return out;
}

// --resume with an FMU (FMI 2.0, canSerializeFMUstate): the counter run by a hand-started
// fmu_adapter is killed (kill -9) after a checkpoint; a new fmu_adapter and cosim_master --resume
// finish the run, and the record and the CSV equal an uninterrupted run's bit for bit. The
// counter's state (its time and count) comes back from the serialized FMU state: a fresh
// instance would refuse the first step (it is at t = 0) and count from 0.
TEST(FmuResume, AKilledFmuAdapterResumesFromItsSerializedState) {
  const std::string fmu = fmutest::pack(fmutest::counter_fmu_entries("1.5"));
  const auto d = kill_and_resume("counter.yaml", "counter",
                                 {"time.end=20", "time.macro_step=0.001", "checkpoints.every=0.1",
                                  "participants.counter.parameters.fmu=" + fmu, "participants.counter.parameters.start.stop_at=1e300"},
                                 {"count"});
  ASSERT_EQ(d.size(), 1u);
  const auto& [x_full, x] = d[0];
  ASSERT_EQ(x_full.size(), 20001u);
  ASSERT_EQ(x.size(), x_full.size());
  EXPECT_EQ(std::memcmp(x.data(), x_full.data(), x.size() * sizeof(double)), 0);
  EXPECT_NEAR(x.back(), 1.5 * 20, 1e-9);
}

// The same with an FMI 3.0 FMU (canSerializeFMUState): VanDerPol from the Reference FMUs, 200 s
// in steps of its fixed internal step (0.01 s).
TEST(FmuResume, AKilledFmuAdapterWithAnFmi3FmuResumes) {
  REQUIRE_FMI3_REFERENCE_FMUS();
  const auto d = kill_and_resume("van_der_pol.yaml", "vdp",
                                 {"time.end=200", "time.macro_step=0.01", "checkpoints.every=1",
                                  "participants.vdp.parameters.fmu=" + fmutest::fmus3_dir() + "/VanDerPol.fmu"},
                                 {"x0", "x1"});
  for (const auto& [full, resumed] : d) {
    ASSERT_EQ(full.size(), 20001u);
    ASSERT_EQ(resumed.size(), full.size());
    EXPECT_EQ(std::memcmp(full.data(), resumed.data(), full.size() * sizeof(double)), 0);
  }
  EXPECT_GT(std::abs(d[0].first.back()), 0.01);  // the oscillator still oscillates at 200 s
}


// ---------------------------------------------------------------------------------------------
// FMI 3.0 (the Reference FMUs in fmi3/, skipped when absent) against the reference CSVs in fmi2/:
// the same model sources with the same fixed-step solver inside doStep.

// Tolerance for the FMI 3.0 builds against the CSVs of the FMI 2.0 builds: the same C model
// and the same forward Euler with the same internal step (BouncingBall 1 ms, Dahlquist 0.1 s,
// VanDerPol 0.1 s), but another binary: the arithmetic order may differ in the last bits
// (measured: see the test output). 1e-9 still catches one step of the wrong length or a wrong
// start value (1e-4 and more, as for FMI 2.0 above).
constexpr double kFmi3Tolerance = 1e-9;

TEST(Fmi3Reference, BouncingBallDahlquistVanDerPolMatchTheirReferencesOverLcm) {
  REQUIRE_FMI3_REFERENCE_FMUS();
  struct Case {
    std::string config, participant, fmu;
    std::vector<std::pair<std::string, std::string>> columns;
  };
  for (const Case& c : std::vector<Case>{{"bouncing_ball.yaml", "ball", "BouncingBall", {{"h", "h"}, {"v", "v"}}},
                                         {"dahlquist.yaml", "dahlquist", "Dahlquist", {{"x", "x"}}},
                                         {"van_der_pol.yaml", "vdp", "VanDerPol", {{"x0", "x0"}, {"x1", "x1"}}}}) {
    const std::string csv = fmutest::temp_path("_" + c.fmu + ".csv");
    ASSERT_EQ(run(c.config, {"participants." + c.participant + ".parameters.fmu=" + fmutest::fmus3_dir() + "/" + c.fmu + ".fmu"}, csv), 0)
        << harness::read_text(csv + ".h5.log");
    std::cerr << c.fmu << " (FMI 3.0): ";
    compare(fmutest::read_csv(csv), fmutest::read_csv(fmutest::fmus_dir() + "/" + c.fmu + "_out.csv"), c.participant + ".",
            c.columns, kFmi3Tolerance);
  }
  // A start value reaches the 3.0 FMU: Dahlquist with k = 1.01 is 1 - 0.101 after one step.
  const std::string k = fmutest::temp_path("_k.csv");
  ASSERT_EQ(run("dahlquist.yaml", {"participants.dahlquist.parameters.fmu=" + fmutest::fmus3_dir() + "/Dahlquist.fmu",
                                   "participants.dahlquist.parameters.start={k: 1.01}"}, k), 0)
      << harness::read_text(k + ".h5.log");
  EXPECT_NEAR(fmutest::read_csv(k).number(1, "dahlquist.x"), 0.899, 1e-12);
}

// Feedthrough 3.0 alone, inputs at their start values: every numeric column of the reference
// CSV exactly (a copy does no arithmetic), Boolean as 0/1; String and Binary, which ports do not
// carry, read from the instance: "Set me!" and 666f6f as in the CSV.
TEST(Fmi3Reference, FeedthroughEveryTypeMatchesItsReferenceOverLcm) {
  REQUIRE_FMI3_REFERENCE_FMUS();
  const std::string csv = fmutest::temp_path(".csv");
  ASSERT_EQ(run("feedthrough3_alone.yaml", {"participants.ft.parameters.fmu=" + fmutest::fmus3_dir() + "/Feedthrough.fmu"}, csv), 0)
      << harness::read_text(csv + ".h5.log");
  const auto ref = fmutest::read_csv(fmutest::fmus_dir() + "/Feedthrough_out.csv");
  const auto ours = fmutest::read_csv(csv);
  std::vector<std::pair<std::string, std::string>> numeric;
  for (const char* n : {"Float32_continuous_output", "Float32_discrete_output", "Float64_continuous_output",
                        "Float64_discrete_output", "Int8_output", "UInt8_output", "Int16_output", "UInt16_output",
                        "Int32_output", "UInt32_output", "Int64_output", "UInt64_output", "Enumeration_output"})
    numeric.push_back({n, n});
  compare(ours, ref, "ft.", numeric, 0.0);
  for (std::size_t i = 0; i < ours.rows.size(); ++i)
    EXPECT_EQ(ours.number(i, "ft.Boolean_output"), ref.rows[i][ref.column("Boolean_output")] == "true" ? 1.0 : 0.0) << i;
  fmu::FmuModel m(YAML::Node(YAML::NodeType::Map), "");
  YAML::Node p = yaml("outputs: [{name: y, scalar: Int8_output}]");
  p["fmu"] = fmutest::fmus3_dir() + "/Feedthrough.fmu";
  m.configure(p, run_info(2.0, 0.1));
  m.step(cosim::StepInputs(cosim::TimePoint{}, cosim::seconds_to_time_point(0.1, "t"), cosim::Polynomials{}), false);
  EXPECT_EQ(m.value_text("String_output"), ref.rows[1][ref.column("String_output")]);
  EXPECT_EQ(m.value_text("Binary_output"), ref.rows[1][ref.column("Binary_output")]);
}

// Every FMI 3.0 type through ports and start values: each input set, copied by the FMU, read
// back exactly; the ends of each integer range pass, one beyond is refused with the type named;
// String and Binary start values reach the FMU; wrong start values are refused at configure.
TEST(Fmi3Types, EveryTypeRoundTripsAndRangesAreChecked) {
  REQUIRE_FMI3_REFERENCE_FMUS();
  const std::vector<std::string> types{"Float32_continuous", "Float64_continuous", "Int8", "UInt8", "Int16", "UInt16",
                                       "Int32", "UInt32", "Int64", "UInt64", "Boolean", "Enumeration"};
  std::string in, out;
  for (const auto& t : types) {
    in += (in.empty() ? "" : ", ") + std::string("{name: i_") + t + ", scalar: " + t + "_input}";
    out += (out.empty() ? "" : ", ") + std::string("{name: o_") + t + ", scalar: " + t + "_output}";
  }
  fmu::FmuModel m(YAML::Node(YAML::NodeType::Map), "");
  YAML::Node p = yaml("{start: {String_input: 'hello, FMI 3', Binary_input: 00ff10, Int64_input: -9223372036854775808, "
                      "UInt64_input: 18446744073709551615, Float64_tunable_parameter: 2.5, Float64_fixed_parameter: 1.5}, "
                      "inputs: [" + in + "], outputs: [" + out + "]}");
  p["fmu"] = fmutest::fmus3_dir() + "/Feedthrough.fmu";
  m.configure(p, run_info(2.0, 0.1));
  EXPECT_EQ(m.value_text("String_output"), "hello, FMI 3");
  EXPECT_EQ(m.value_text("Binary_output"), "00ff10");
  EXPECT_EQ(m.value_text("Int64_output"), "-9223372036854775808");  // exact, beyond 2^53
  EXPECT_EQ(m.value_text("UInt64_output"), "18446744073709551615");
  EXPECT_EQ(m.value_text("Float64_fixed_parameter"), "1.5");
  const std::map<std::string, double> values{
      {"Float32_continuous", 0.1}, {"Float64_continuous", 0.1}, {"Int8", -128}, {"UInt8", 255}, {"Int16", -32768},
      {"UInt16", 65535}, {"Int32", 2147483647}, {"UInt32", 4294967295.0}, {"Int64", -9007199254740992.0},
      {"UInt64", 9007199254740992.0}, {"Boolean", 1}, {"Enumeration", 2}};
  cosim::Polynomials polys;
  for (const auto& [t, v] : values) polys["i_" + t] = cosim::InputPolynomial::constant(cosim::SignalKind::Scalar, {v});
  const auto r = m.step(cosim::StepInputs(cosim::TimePoint{}, cosim::seconds_to_time_point(0.1, "t"), polys), false);
  for (const auto& [t, v] : values) {
    const double expect = t == "Float32_continuous" ? static_cast<double>(0.1f) : v;  // rounded to float
    EXPECT_EQ(r.outputs.at("o_" + t).value[0], expect) << t;
  }
  EXPECT_EQ(m.value_text("Int8_output"), "-128");
  // One beyond each range: refused (the step is rejected, state kept), naming the type.
  for (const auto& [t, v] : std::vector<std::pair<std::string, double>>{
           {"Int8", 128}, {"UInt8", -1}, {"Int16", 32768}, {"UInt16", 65536}, {"Int32", 2147483648.0},
           {"UInt32", 4294967296.0}, {"Int64", 9223372036854775808.0}, {"UInt64", 18446744073709551616.0}}) {
    cosim::Polynomials bad = polys;
    bad["i_" + t] = cosim::InputPolynomial::constant(cosim::SignalKind::Scalar, {v});
    try {
      m.step(cosim::StepInputs(cosim::seconds_to_time_point(0.1, "t"), cosim::seconds_to_time_point(0.2, "t"), bad), false);
      ADD_FAILURE() << t << " took " << v;
    } catch (const cosim::InputError& e) {
      EXPECT_HAS(e.what(), "does not fit FMU " + t + " variable '" + t + "_input' (" + t + " range)");
    }
  }
  // Start values of the wrong type or out of range, refused at configure with the key.
  for (const auto& [start, expect] : std::vector<std::pair<std::string, std::string>>{
           {"{Int8_input: 200}", "start.Int8_input: 'Int8_input' is an FMI Int8 variable; expected an integer from -128 to 127, got '200'"},
           {"{UInt16_input: 2.5}", "start.UInt16_input: 'UInt16_input' is an FMI UInt16 variable; expected an integer (UInt16), got '2.5'"},
           {"{UInt64_input: -1}", "expected an integer from 0 to 18446744073709551615, got '-1'"},
           {"{Float32_continuous_input: 1e39}", "expected a number within the Float32 range"},
           {"{Binary_input: xyz}", "'Binary_input' is an FMI Binary variable; expected hex digits, two per byte (e.g. 666f6f), got 'xyz'"},
           {"{Enumeration_input: Option 3}", "expected an item of Option: Option 1 (1), Option 2 (2), got 'Option 3'"},
           {"{Float64_continuous_output: 1}", "'Float64_continuous_output' is calculated by the FMU"}}) {
    fmu::FmuModel bad(YAML::Node(YAML::NodeType::Map), "");
    YAML::Node q = yaml("{start: " + start + ", outputs: [{name: y, scalar: Int8_output}]}");
    q["fmu"] = fmutest::fmus3_dir() + "/Feedthrough.fmu";
    try {
      bad.configure(q, run_info());
      ADD_FAILURE() << start << " was accepted";
    } catch (const std::exception& e) {
      EXPECT_HAS(e.what(), expect);
    }
  }
  // String and Binary are not port types.
  EXPECT_HAS(configure_error(fmutest::fmus3_dir() + "/Feedthrough.fmu", "outputs: [{name: s, scalar: String_output}]"),
             "'String_output' is a String variable; ports carry numbers");
  EXPECT_HAS(configure_error(fmutest::fmus3_dir() + "/Feedthrough.fmu", "outputs: [{name: s, scalar: Binary_output}]"),
             "'Binary_output' is a Binary variable; ports carry numbers");
}

// Repeated steps through fmi3GetFMUState/SetFMUState are bit-identical, and a checkpoint
// (fmi3SerializeFMUState) loaded into a new instance continues bit for bit: VanDerPol 3.0.
TEST(Fmi3State, RepeatedStepsAndSerializedCheckpointsAreBitIdentical) {
  REQUIRE_FMI3_REFERENCE_FMUS();
  const std::string mapping = "outputs: [{name: x0, scalar: x0}, {name: x1, scalar: x1}]";
  auto make = [&](fmu::FmuModel& m) {
    YAML::Node p = yaml(mapping);
    p["fmu"] = fmutest::fmus3_dir() + "/VanDerPol.fmu";
    m.configure(p, run_info(20.0, 0.01));
  };
  auto step = [](fmu::FmuModel& m, int i) {  // [0.01 i, 0.01 (i + 1)], the reference CSV's rows
    const cosim::Duration h(10'000'000);
    const auto r = m.step(cosim::StepInputs(cosim::TimePoint{} + h * i, cosim::TimePoint{} + h * (i + 1), cosim::Polynomials{}), false);
    return std::array<double, 2>{r.outputs.at("x0").value[0], r.outputs.at("x1").value[0]};
  };
  fmu::FmuModel a(YAML::Node(YAML::NodeType::Map), "");
  make(a);
  EXPECT_TRUE(a.can_repeat());
  EXPECT_TRUE(a.can_checkpoint());
  std::vector<std::array<double, 2>> once;
  for (int i = 0; i < 100; ++i) {
    a.save_snapshot();
    const auto first = step(a, i);
    a.restore_snapshot();
    const auto again = step(a, i);
    EXPECT_EQ(std::memcmp(first.data(), again.data(), sizeof first), 0) << i;
    once.push_back(again);
  }
  const std::string ckpt = fmutest::temp_path(".ckpt");
  a.save_checkpoint(ckpt);
  std::vector<std::array<double, 2>> rest;
  for (int i = 100; i < 150; ++i) rest.push_back(step(a, i));
  fmu::FmuModel b(YAML::Node(YAML::NodeType::Map), "");
  make(b);
  b.load_checkpoint(ckpt);
  for (int i = 100; i < 150; ++i) {
    const auto r = step(b, i);
    EXPECT_EQ(std::memcmp(r.data(), rest[i - 100].data(), sizeof r), 0) << i;
  }
  const auto ref = fmutest::read_csv(fmutest::fmus_dir() + "/VanDerPol_out.csv");
  for (std::size_t i = 0; i < 100; ++i) EXPECT_NEAR(once[i][0], ref.number(i + 1, "x0"), kFmi3Tolerance) << i;
  // A checkpoint of another FMU is refused by its GUID (instantiation token).
  fmu::FmuModel c(YAML::Node(YAML::NodeType::Map), "");
  YAML::Node p = yaml("outputs: [{name: x, scalar: x}]");
  p["fmu"] = fmutest::fmus3_dir() + "/Dahlquist.fmu";
  c.configure(p, run_info(20.0, 0.01));
  try {
    c.load_checkpoint(ckpt);
    ADD_FAILURE() << "a VanDerPol checkpoint was loaded into Dahlquist";
  } catch (const fmu::FmuError& e) {
    EXPECT_HAS(e.what(), "resume with the FMU the run started with");
  }
}


// ---------------------------------------------------------------------------------------------
// SSP 1.0: a package of the project's two oscillator-half FMUs (build/fmu/) against its YAML
// twin, and bad SSP files refused with the file, the line and the reason.

namespace ssptest {

const char* kUnits = R"(  <ssd:Units>
    <ssc:Unit name="m"><ssc:BaseUnit m="1"/></ssc:Unit>
    <ssc:Unit name="mm"><ssc:BaseUnit m="1" factor="0.001"/></ssc:Unit>
    <ssc:Unit name="m/s"><ssc:BaseUnit m="1" s="-1"/></ssc:Unit>
    <ssc:Unit name="N"><ssc:BaseUnit kg="1" m="1" s="-2"/></ssc:Unit>
  </ssd:Units>
)";

// The oscillator as SSD: mass1's parameters from an SSV file, mass2's inline; x2 in `x_unit`.
std::string ssd(const std::string& x_unit = "m", const std::string& extra_connection = "") {
  return std::string(R"(<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="oscillator"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssd:System name="dual_mass">
    <ssd:Elements>
      <ssd:Component name="mass1" type="application/x-fmu-sharedlibrary" source="resources/oscillator_mass1.fmu">
        <ssd:Connectors>
          <ssd:Connector name="force" kind="input"><ssc:Real unit="N"/></ssd:Connector>
          <ssd:Connector name="x" kind="output"><ssc:Real unit="m"/></ssd:Connector>
          <ssd:Connector name="v" kind="output"><ssc:Real unit="m/s"/></ssd:Connector>
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding source="resources/mass1.ssv"/>
        </ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="mass2" type="application/x-fmu-sharedlibrary" source="resources/oscillator_mass2.fmu">
        <ssd:Connectors>
          <ssd:Connector name="x" kind="input"><ssc:Real unit=")") + x_unit + R"("/></ssd:Connector>
          <ssd:Connector name="v" kind="input"><ssc:Real unit="m/s"/></ssd:Connector>
          <ssd:Connector name="force" kind="output"><ssc:Real unit="N"/></ssd:Connector>
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding>
            <ssd:ParameterValues>
              <ssv:ParameterSet version="1.0" name="mass2">
                <ssv:Parameters>
                  <ssv:Parameter name="mass"><ssv:Real value="1"/></ssv:Parameter>
                  <ssv:Parameter name="stiffness"><ssv:Real value="10"/></ssv:Parameter>
                  <ssv:Parameter name="damping"><ssv:Real value="0.2"/></ssv:Parameter>
                  <ssv:Parameter name="coupling_stiffness"><ssv:Real value="1000"/></ssv:Parameter>
                  <ssv:Parameter name="coupling_damping"><ssv:Real value="2"/></ssv:Parameter>
                  <ssv:Parameter name="position"><ssv:Real value="0"/></ssv:Parameter>
                  <ssv:Parameter name="velocity"><ssv:Real value="0"/></ssv:Parameter>
                  <ssv:Parameter name="x"><ssv:Real value="0.1"/></ssv:Parameter>
                  <ssv:Parameter name="v"><ssv:Real value="0"/></ssv:Parameter>
                  <ssv:Parameter name="inner_step"><ssv:Real value="5e-6"/></ssv:Parameter>
                </ssv:Parameters>
              </ssv:ParameterSet>
            </ssd:ParameterValues>
          </ssd:ParameterBinding>
        </ssd:ParameterBindings>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="mass1" startConnector="x" endElement="mass2" endConnector="x"/>
      <ssd:Connection startElement="mass1" startConnector="v" endElement="mass2" endConnector="v"/>
      <ssd:Connection startElement="mass2" startConnector="force" endElement="mass1" endConnector="force"/>
)" + extra_connection + R"(    </ssd:Connections>
  </ssd:System>
)" + kUnits + R"(  <ssd:DefaultExperiment startTime="0" stopTime="0.05"/>
</ssd:SystemStructureDescription>
)";
}

const char* kMass1Ssv = R"(<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet version="1.0" name="mass1" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssv:Parameters>
    <ssv:Parameter name="mass"><ssv:Real value="1"/></ssv:Parameter>
    <ssv:Parameter name="stiffness"><ssv:Real value="10"/></ssv:Parameter>
    <ssv:Parameter name="damping"><ssv:Real value="0.2"/></ssv:Parameter>
    <ssv:Parameter name="position"><ssv:Real value="0.1"/></ssv:Parameter>
    <ssv:Parameter name="velocity"><ssv:Real value="0"/></ssv:Parameter>
    <ssv:Parameter name="inner_step"><ssv:Real value="5e-6"/></ssv:Parameter>
  </ssv:Parameters>
</ssv:ParameterSet>
)";

std::string fmu(int side) { return std::string(FMU_EXPORT_DIR) + "/oscillator_mass" + std::to_string(side) + ".fmu"; }

// The system as a folder with SystemStructure.ssd (returns the .ssd's path).
std::string folder(const std::string& name, const std::string& ssd_text) {
  namespace fs = std::filesystem;
  const fs::path dir = fmutest::temp_path("_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir / "resources");
  fs::copy_file(fmu(1), dir / "resources/oscillator_mass1.fmu");
  fs::copy_file(fmu(2), dir / "resources/oscillator_mass2.fmu");
  std::ofstream(dir / "resources/mass1.ssv") << kMass1Ssv;
  std::ofstream(dir / "SystemStructure.ssd") << ssd_text;
  return (dir / "SystemStructure.ssd").string();
}

// The YAML twin: configs/oscillator_fmu.yaml's system written out by hand.
std::string twin(const std::string& predictor_lines, const std::string& connection_predictor) {
  std::string p = connection_predictor.empty() ? "" : ", predictor: " + connection_predictor;
  return "time: {start: 0, end: 0.05, macro_step: 5.0e-4}\n" + predictor_lines +
         "participants:\n"
         "  mass1:\n"
         "    launch: [fmu_adapter]\n"
         "    parameters:\n"
         "      fmu: " + fmu(1) + "\n"
         "      start: {mass: 1, stiffness: 10, damping: 0.2, position: 0.1, velocity: 0, inner_step: 5.0e-6}\n"
         "      inputs: [{name: force, scalar: force}]\n"
         "      outputs: [{name: x, scalar: x}, {name: v, scalar: v}]\n"
         "  mass2:\n"
         "    launch: [fmu_adapter]\n"
         "    parameters:\n"
         "      fmu: " + fmu(2) + "\n"
         "      start: {mass: 1, stiffness: 10, damping: 0.2, coupling_stiffness: 1000, coupling_damping: 2,\n"
         "              position: 0, velocity: 0, x: 0.1, v: 0, inner_step: 5.0e-6}\n"
         "      inputs: [{name: x, scalar: x}, {name: v, scalar: v}]\n"
         "      outputs: [{name: force, scalar: force}]\n"
         "connections:\n"
         "  - {from: mass1.x, to: mass2.x" + p + "}\n"
         "  - {from: mass1.v, to: mass2.v" + p + "}\n"
         "  - {from: mass2.force, to: mass1.force" + p + "}\n"
         "output: {progress: off}\n";
}

int master(const std::string& config, const std::string& out, const std::vector<std::string>& sets) {
  std::vector<std::string> a{harness::bin("cosim_master"), config, "--output", out, "--csv", out + ".csv"};
  for (const auto& s : sets) a.insert(a.end(), {"--set", s});
  a.insert(a.end(), {"--set", "bus.url=" + harness::bus_url(), "--set", "output.progress=off"});
  auto p = harness::spawn(a, out + ".log");
  return harness::wait_for(p, 120);
}

}  // namespace ssptest

// `cosim_master system.ssp` (the package zipped: SystemStructure.ssd, the two FMUs, an SSV) and
// `cosim_master twin.yaml` give the same CSV and the same outputs bit for bit; so do a YAML that
// names the .ssd with a predictor for its connections (order 1, start-up iterations) and its
// twin with that predictor on every connection.
TEST(SspImport, ThePackageOfTheOscillatorHalvesRunsLikeItsYamlTwin) {
  namespace fs = std::filesystem;
  ASSERT_TRUE(fs::exists(ssptest::fmu(1)) && fs::exists(ssptest::fmu(2))) << "build the oscillator FMUs (build/fmu/)";
  const std::string ssd = ssptest::folder("sys", ssptest::ssd());
  const std::string package = fmutest::temp_path(".ssp");
  fmutest::write_zip(package, {{"SystemStructure.ssd", fmutest::slurp(ssd)},
                               {"resources/oscillator_mass1.fmu", fmutest::slurp(ssptest::fmu(1))},
                               {"resources/oscillator_mass2.fmu", fmutest::slurp(ssptest::fmu(2))},
                               {"resources/mass1.ssv", ssptest::kMass1Ssv}});
  const std::string twin = fmutest::temp_path("_twin.yaml");
  std::ofstream(twin) << ssptest::twin("", "");
  const std::string a = fmutest::temp_path("_ssp.h5"), b = fmutest::temp_path("_twin.h5");
  ASSERT_EQ(ssptest::master(package, a, {"time.macro_step=5.0e-4"}), 0) << harness::read_text(a + ".log");
  ASSERT_EQ(ssptest::master(twin, b, {}), 0) << harness::read_text(b + ".log");
  const std::string csv = harness::read_text(a + ".csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 102);  // header, t = 0 .. 0.05
  EXPECT_TRUE(csv == harness::read_text(b + ".csv")) << "the SSP run's CSV differs from its YAML twin's";
  for (const char* d : {"participants/mass1/outputs/x", "participants/mass1/outputs/v", "participants/mass2/outputs/force"}) {
    const auto x = harness::read_dataset(a, d), y = harness::read_dataset(b, d);
    ASSERT_EQ(x.size(), 101u) << d;
    EXPECT_EQ(std::memcmp(x.data(), y.data(), x.size() * sizeof(double)), 0) << d;
  }
  EXPECT_GT(std::abs(harness::read_dataset(a, "participants/mass2/outputs/force").back()), 1e-3);  // something moved
  EXPECT_HAS(harness::read_string(a, "config"), "# generated by cosim_master from " + package + " (SSP 1.0)");

  // A YAML naming the .ssd, with a predictor: the same as the twin with that predictor.
  const std::string with = fmutest::temp_path("_with.yaml"), twin1 = fmutest::temp_path("_twin1.yaml");
  std::ofstream(with) << "ssp: {file: " << ssd << ", predictor: linear}\ntime: {macro_step: 5.0e-4}\n"
                      << "startup_iterations: 2\npredictors: {linear: {order: 1}}\noutput: {progress: off}\n";
  std::ofstream(twin1) << ssptest::twin("startup_iterations: 2\npredictors: {linear: {order: 1}}\n", "linear");
  const std::string c = fmutest::temp_path("_with.h5"), d = fmutest::temp_path("_twin1.h5");
  ASSERT_EQ(ssptest::master(with, c, {}), 0) << harness::read_text(c + ".log");
  ASSERT_EQ(ssptest::master(twin1, d, {}), 0) << harness::read_text(d + ".log");
  EXPECT_TRUE(harness::read_text(c + ".csv") == harness::read_text(d + ".csv")) << "the .ssd run differs from its YAML twin";
  EXPECT_FALSE(harness::read_text(c + ".csv") == csv) << "the predictor made no difference";
  EXPECT_EQ(harness::read_dataset(c, "timing/iterations").at(1), 3);
}

// Units: mass2.x declared in mm gets x in mm (factor 1000 on its input port); a linear
// transformation on the connection is used as given.
TEST(SspImport, UnitConversionGoesOnTheConsumersInputPort) {
  const YAML::Node mm = ssp::system_config(ssptest::folder("mm", ssptest::ssd("mm")));
  const YAML::Node port = mm["participants"]["mass2"]["parameters"]["inputs"][0];
  EXPECT_EQ(port["name"].as<std::string>(), "x");
  EXPECT_DOUBLE_EQ(port["factor"].as<double>(), 1000.0);
  EXPECT_DOUBLE_EQ(port["offset"].as<double>(), 0.0);
  EXPECT_FALSE(mm["participants"]["mass2"]["parameters"]["inputs"][1]["factor"]);  // m/s to m/s: none
  EXPECT_EQ(mm["time"]["end"].as<double>(), 0.05);
  EXPECT_EQ(mm["participants"]["mass1"]["parameters"]["start"]["position"].as<double>(), 0.1);  // from the SSV
  // The port conversion itself, through fmu_adapter: the echo FMU gets 1000 x + 5.
  Echo e("{inputs: [{name: u, scalar: u0, factor: 1000, offset: 5}], outputs: [{name: y, scalar: y0}]}");
  EXPECT_EQ(e.step({{"u", {cosim::SignalKind::Scalar, {0.25}}}}).at("y").value[0], 255.0);
}

TEST(SspImport, BadFilesAreRefusedWithFileLineAndReason) {
  auto error = [](const std::string& path) {
    try {
      ssp::system_config(path);
    } catch (const ssp::SspError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  // Malformed XML: the line of the damage.
  std::string text = ssptest::ssd();
  text = fmutest::replace_all(text, "</ssd:Elements>", "</ssd:Element>");
  std::string path = ssptest::folder("malformed", text);
  EXPECT_HAS(error(path), path + ":45: malformed XML");
  // A component whose FMU is not in the package.
  path = ssptest::folder("missing", fmutest::replace_all(ssptest::ssd(), "resources/oscillator_mass2.fmu", "resources/nowhere.fmu"));
  EXPECT_HAS(error(path), path + ":18: component 'mass2': its FMU resources/nowhere.fmu is missing");
  // A connection to a component that is not there, and to a connector that is not there.
  path = ssptest::folder("dangling", ssptest::ssd("m", "      <ssd:Connection startElement=\"mass1\" startConnector=\"x\" endElement=\"mass3\" endConnector=\"x\"/>\n"));
  EXPECT_HAS(error(path), path + ":50: dangling connection: its endElement 'mass3' is not a component of the system");
  path = ssptest::folder("dangling2", fmutest::replace_all(ssptest::ssd(), "startConnector=\"v\"", "startConnector=\"w\""));
  EXPECT_HAS(error(path), path + ":48: dangling connection: component 'mass1' has no connector 'w'");
  // A unit that <ssd:Units> does not define.
  path = ssptest::folder("unit", ssptest::ssd("furlong"));
  EXPECT_HAS(error(path), path + ":20: connector 'mass2.x' has unit 'furlong', which <ssd:Units> does not define");
  // Units of different quantities.
  path = ssptest::folder("dims", ssptest::ssd("N"));
  EXPECT_HAS(error(path), path + ":47: connection mass1.x [m] -> mass2.x [N]: the units measure different quantities");
  // A damaged SSV names its own file and line.
  path = ssptest::folder("ssv", ssptest::ssd());
  std::ofstream(std::filesystem::path(path).parent_path() / "resources/mass1.ssv") << "<ssv:ParameterSet>\n<ssv:Parameters>\n</ssv:ParameterSet>\n";
  EXPECT_HAS(error(path), "resources/mass1.ssv:3: malformed XML");
  // Through cosim_master: exit 2 with the same message.
  const std::string out = fmutest::temp_path("_bad.h5");
  EXPECT_EQ(ssptest::master(ssptest::folder("unit2", ssptest::ssd("furlong")), out, {"time.macro_step=5.0e-4"}), 2);
  EXPECT_HAS(harness::read_text(out + ".log"), "cosim_master: config refused: ");
  EXPECT_HAS(harness::read_text(out + ".log"), "has unit 'furlong', which <ssd:Units> does not define");
}


// An FMI 3.0 FMU that ends itself (terminateSimulation with fmi3Discard at stop_at = 0.25 inside
// the step [0.2, 0.3]): the step ends there, with the outputs there, and says so.
TEST(FmuEnds, AnFmi3FmuThatSetsTerminateSimulationEndsTheStep) {
  fmu::FmuModel m(YAML::Node(YAML::NodeType::Map), "");
  YAML::Node p = yaml("{instance: a3, start: {stop_at: 0.25}, outputs: [{name: total, scalar: total}]}");
  p["fmu"] = fmutest::pack(fmutest::array_fmu3_entries());
  m.configure(p, run_info(1.0, 0.1));
  cosim::Polynomials none;
  for (int i = 0; i < 2; ++i)
    EXPECT_FALSE(m.step(cosim::StepInputs(cosim::seconds_to_time_point(0.1 * i, "t"), cosim::seconds_to_time_point(0.1 * (i + 1), "t"), none), false).ended_at);
  const auto r = m.step(cosim::StepInputs(cosim::seconds_to_time_point(0.2, "t"), cosim::seconds_to_time_point(0.3, "t"), none), false);
  ASSERT_TRUE(r.ended_at);
  EXPECT_EQ(*r.ended_at, cosim::seconds_to_time_point(0.25, "t"));
  EXPECT_HAS(r.ended_reason, "(instance 'a3') ended itself: fmi3DoStep at t = 0.2 s (step 0.1 s) set terminateSimulation: the FMU "
                             "ended the simulation at its last successful time 0.25 s");
}

// FMI 3.0 arrays and a structural parameter (the test-only array_fmu3, runs everywhere): n = 4
// set in Configuration Mode resizes u and y; array start values as lists; ports on elements
// (1-based, row-major); y = scale u, total = sum(u) + offsets, read back exactly.
TEST(Fmi3Arrays, ElementsInPortsAndArrayStartValuesWithAStructuralSize) {
  const std::string fmu = fmutest::pack(fmutest::array_fmu3_entries());
  fmu::FmuModel m(YAML::Node(YAML::NodeType::Map), "");
  YAML::Node p = yaml("{start: {n: 4, u: [1, 2, 3, 4], offsets: [10, 20], scale: 3}, inputs: [{name: u2, scalar: 'u[2]'}], "
                      "outputs: [{name: y1, scalar: 'y[1]'}, {name: y2, scalar: 'y[2]'}, {name: y4, scalar: 'y[4]'}, {name: total, scalar: total}]}");
  p["fmu"] = fmu;
  m.configure(p, run_info(1.0, 0.1));
  const auto initial = m.initial_outputs();
  EXPECT_EQ(initial.at("y4").value[0], 12.0);
  EXPECT_EQ(initial.at("total").value[0], 40.0);  // 1 + 2 + 3 + 4 + 10 + 20
  cosim::Polynomials in{{"u2", cosim::InputPolynomial::constant(cosim::SignalKind::Scalar, {7.0})}};
  const auto r = m.step(cosim::StepInputs(cosim::TimePoint{}, cosim::seconds_to_time_point(0.1, "t"), in), false).outputs;
  EXPECT_EQ(r.at("y1").value[0], 3.0);
  EXPECT_EQ(r.at("y2").value[0], 21.0);  // the element the port set, the others kept
  EXPECT_EQ(r.at("y4").value[0], 12.0);
  EXPECT_EQ(r.at("total").value[0], 45.0);
  for (const auto& [mapping, expect] : std::vector<std::pair<std::string, std::string>>{
           {"{outputs: [{name: y, scalar: y}]}", "outputs.0.scalar: 'y' is an array (1 <Dimension>); a port carries one number: name an element, e.g. y[1] (1-based)"},
           {"{start: {n: 4}, outputs: [{name: y, scalar: 'y[5]'}]}", "outputs.0.scalar: 'y[5]': index 5 is beyond the size 4 of dimension 1"},
           {"{outputs: [{name: y, scalar: 'y[1,1]'}]}", "'y' has 1 dimension(s), so give 1 index(es)"},
           {"{outputs: [{name: y, scalar: 'total[1]'}]}", "'total' is not an array"},
           {"{start: {n: 4, u: [1, 2, 3]}, outputs: [{name: t, scalar: total}]}", "start.u: 'u' has 4 values, the list 3"},
           {"{start: {offsets: [1.5, 2]}, outputs: [{name: t, scalar: total}]}", "start.offsets.0: expected an integer in the Int32 range, got 1.5"},
           {"{start: {u: 1}, outputs: [{name: t, scalar: total}]}", "'u' is an FMI Float64 variable; expected a list of its values (it is an array)"}}) {
    try {
      fmu::FmuModel bad(YAML::Node(YAML::NodeType::Map), "");
      YAML::Node q = yaml(mapping);
      q["fmu"] = fmu;
      bad.configure(q, run_info(1.0, 0.1));
      ADD_FAILURE() << mapping << " was accepted";
    } catch (const std::exception& e) {
      EXPECT_HAS(e.what(), expect);
    }
  }
}

}  // namespace
