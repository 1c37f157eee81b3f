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
// Through cosim_master over LCM.

std::string config(const std::string& name) { return "tests/fmu/" + name; }

// Runs the master on a config of tests/fmu with the CSV written; returns the exit code.
int run(const std::string& cfg, std::vector<std::string> overrides, const std::string& csv, double timeout = 90) {
  overrides.push_back("output.csv=" + csv);
  return harness::run_master(overrides, csv + ".h5", timeout, config(cfg));
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
// and says which FMU and what to change; with startup_iterations: 0 the same FMU runs.
TEST(FmuState, FmuWithoutStateIsRefusedForStartupIterationsOverLcm) {
  REQUIRE_REFERENCE_FMUS();
  Entries e = fmutest::read_zip(fmutest::fmus_dir() + "/Feedthrough.fmu");
  std::string& xml = fmutest::entry(e, "modelDescription.xml");
  const std::string cs = xml.substr(xml.find("<CoSimulation"));
  const std::string cs_nostate = fmutest::replace_all(cs.substr(0, cs.find('>')), "canGetAndSetFMUstate=\"true\"",
                                                      "canGetAndSetFMUstate=\"false\"");
  xml.replace(xml.find("<CoSimulation"), cs.find('>'), cs_nostate);
  ASSERT_NE(xml.find("canGetAndSetFMUstate=\"false\""), std::string::npos);
  const std::string fmu = fmutest::pack(e, "_nostate.fmu");
  const std::string motion = fmutest::temp_path("_motion.csv");
  std::ofstream(motion) << "time,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n1,1,0,0,1,0,0,0\n";
  const std::vector<std::string> base{"participants.ft.parameters.fmu=" + fmu, "participants.source.parameters.tools.0.csv=" + motion,
                                      "predictors.hold.order=1", "startup_iterations=2"};
  const std::string csv = fmutest::temp_path(".csv");
  ASSERT_EQ(run("feedthrough.yaml", base, csv), 2);
  const std::string log = harness::read_text(csv + ".h5.log");
  EXPECT_HAS(log, "cosim_master: config refused: startup_iterations: 2 (with predictor order 1) redoes the first steps, "
                  "but participant 'ft' cannot repeat a step (FMU FmuState_FmuWithoutStateIsRefusedForStartupIterationsOverLcm_nostate.fmu (model 'Feedthrough')");
  EXPECT_HAS(log, "declares canGetAndSetFMUstate=\"false\"");
  EXPECT_HAS(log, "set startup_iterations: 0");
  auto no_iterations = base;
  no_iterations.push_back("startup_iterations=0");
  const std::string ok = fmutest::temp_path("_ok.csv");
  EXPECT_EQ(run("feedthrough.yaml", no_iterations, ok), 0) << harness::read_text(ok + ".h5.log");
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
        EXPECT_TRUE(r && r->status == cosim::step_reply_t::OK) << (r ? r->message : "no reply");
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
