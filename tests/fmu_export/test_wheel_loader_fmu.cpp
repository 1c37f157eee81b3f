// The wheel-loader FMU (build/fmu/wheel_loader.fmu, fmu_export/wheel_loader) against the native
// model (mbs_adapters/wheel_loader): loaded with dlopen and driven through its fmi2 functions
// against wheel_loader::WheelLoader in the same process, and under cosim_master through
// fmu_adapter against wheel_loader_adapter on a recorded soil run (docs/fmi.md).
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>

#include "../oscillator/replay_harness.hpp"
#include "fmu_loader.hpp"
#include "wheel_loader.hpp"

namespace {

using fmu_test::Instance;
using fmu_test::Library;

const char* const kOutputs[] = {
    "position_x", "position_y", "position_z", "quaternion_w", "quaternion_x", "quaternion_y",
    "quaternion_z", "velocity_x", "velocity_y", "velocity_z", "angular_velocity_x", "angular_velocity_y",
    "angular_velocity_z", "a_long", "a_vert", "j_long", "j_vert", "lift_force", "tilt_force", "speed",
    "x_machine", "drive_force", "normal_load", "bucket_pitch", "boom_angle", "edge_x", "edge_z"};
constexpr int kNumOutputs = sizeof(kOutputs) / sizeof(kOutputs[0]);
const char* const kInputs[] = {"force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z",
                               "reference_point_x", "reference_point_y", "reference_point_z"};

// Value references read once (fmu_loader's lookup reads the XML each time).
struct Vrs {
  std::vector<fmi2ValueReference> out, in;
  Vrs() {
    for (const char* n : kOutputs) out.push_back(fmu_test::vr_of("wheel_loader", n));
    for (const char* n : kInputs) in.push_back(fmu_test::vr_of("wheel_loader", n));
  }
};
const Vrs& vrs() {
  static const Vrs v;
  return v;
}

std::vector<double> fmu_outputs(Instance& f) {
  std::vector<double> v(kNumOutputs, NAN);
  EXPECT_EQ(f.lib.fmi2GetReal(f.c, vrs().out.data(), kNumOutputs, v.data()), fmi2OK) << f.log.all();
  return v;
}

fmi2Status set_wrench(Instance& f, const wheel_loader::Wrench& w) {
  double v[9];
  for (int i = 0; i < 3; ++i) v[i] = w.force[i], v[3 + i] = w.torque[i], v[6 + i] = w.point[i];
  return f.lib.fmi2SetReal(f.c, vrs().in.data(), 9, v);
}

// The native model's numbers in the FMU's output order.
std::vector<double> native_outputs(const wheel_loader::WheelLoader& m) {
  const cosim::Kinematics k = m.bucket();
  const wheel_loader::Reports r = m.reports();
  const wheel_loader::V3 e = m.cutting_edge();
  return {k.position[0], k.position[1], k.position[2], k.orientation[0], k.orientation[1], k.orientation[2],
          k.orientation[3], k.velocity[0], k.velocity[1], k.velocity[2], k.angular_velocity[0],
          k.angular_velocity[1], k.angular_velocity[2], r.a_long, r.a_vert, r.j_long, r.j_vert, r.lift_force,
          r.tilt_force, r.speed, r.x_machine, r.drive_force, r.normal_load, r.bucket_pitch, r.boom_angle, e[0],
          e[2]};
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

std::string first_difference(const std::vector<double>& a, const std::vector<double>& b) {
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i)
    if (std::memcmp(&a[i], &b[i], sizeof(double)) != 0) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "%s: %.17g vs %.17g", kOutputs[i], a[i], b[i]);
      return buf;
    }
  return "sizes " + std::to_string(a.size()) + " vs " + std::to_string(b.size());
}

// A soil-like wrench that changes every step: a resisting force growing with the step, a
// lifting part, a torque about a point ahead of the bucket (ground axes).
wheel_loader::Wrench wrench_at_step(int k) {
  wheel_loader::Wrench w;
  const double s = 1 - std::exp(-k / 60.0);
  w.force = {-4.0e4 * s - 3.0e3 * std::sin(0.21 * k), 150.0 * std::cos(0.1 * k), 1.5e4 * s};
  w.torque = {20.0 * s, 6.0e3 * s + 800.0 * std::sin(0.17 * k), -35.0 * s};
  w.point = {5.1 + 1e-3 * k, 0.05, 0.35};
  return w;
}

constexpr double kH = 1e-3;  // communication step, as configs/wheel_loader.yaml

}  // namespace

TEST(WheelLoaderFmu, TheFmuIsTheNativeModelBitForBit) {
  Library lib("wheel_loader");
  Instance f(lib, "wheel_loader");
  ASSERT_NE(f.c, nullptr) << f.log.all();
  ASSERT_EQ(f.set("initial_position", 2.15), fmi2OK);
  ASSERT_EQ(f.initialize(0, 1), fmi2OK) << f.log.all();
  wheel_loader::Parameters p;
  p.initial_position = 2.15;
  wheel_loader::WheelLoader native(p, 0.0);
  ASSERT_TRUE(same_bits(fmu_outputs(f), native_outputs(native)))
      << "after initialization: " << first_difference(fmu_outputs(f), native_outputs(native));
  // 400 steps of 1 ms with a wrench that changes every step, held over each step as the native
  // adapter holds it under a constant force predictor.
  int identical = 0;
  for (int k = 0; k < 400; ++k) {
    const wheel_loader::Wrench w = wrench_at_step(k);
    ASSERT_EQ(set_wrench(f, w), fmi2OK);
    ASSERT_EQ(lib.fmi2DoStep(f.c, k * kH, kH, fmi2True), fmi2OK) << f.log.all();
    native.set_wrench([w](double) { return w; });
    native.advance(static_cast<double>((k + 1) * 1000000LL) * 1e-9);
    const auto a = fmu_outputs(f), b = native_outputs(native);
    EXPECT_TRUE(same_bits(a, b)) << "step " << k << ": " << first_difference(a, b);
    identical += same_bits(a, b) ? 1 : 0;
  }
  EXPECT_EQ(identical, 400);
  // The wrench did something: the machine is slower than without it, the pins loaded.
  wheel_loader::WheelLoader free_machine(p, 0.0);
  free_machine.advance(0.4);
  const auto end = fmu_outputs(f);
  std::printf("after 0.4 s: speed %.4f m/s (without the wrench %.4f), a_long %.0f N\n", end[19],
              free_machine.reports().speed, end[13]);
  EXPECT_GT(std::abs(end[19] - free_machine.reports().speed), 1e-3);
  EXPECT_EQ(lib.fmi2Terminate(f.c), fmi2OK);
}

TEST(WheelLoaderFmu, AMachineFileAndParametersGiveTheNativeMachine) {
  Library lib("wheel_loader");
  // configs/wheel_loader/machine.yaml equals the built-in defaults; a Real parameter set to
  // another value than its default overrides the file, machine_parameters amend it.
  Instance f(lib, "wheel_loader");
  ASSERT_EQ(f.set_string("machine_config", std::string(SOURCE_DIR) + "/configs/wheel_loader/machine.yaml"), fmi2OK);
  ASSERT_EQ(f.set_string("machine_parameters", "{maneuver.speed: [[0, 1.2], [0.1, 0.6]], bucket.mass: 3000}"), fmi2OK);
  ASSERT_EQ(f.set("initial_position", 2.15), fmi2OK);
  ASSERT_EQ(f.set("frame.mass", 21000), fmi2OK);
  ASSERT_EQ(f.initialize(0, 1), fmi2OK) << f.log.all();
  wheel_loader::Parameters p;
  p.initial_position = 2.15;
  p.frame.mass = 21000;
  p.bucket.mass = 3000;
  p.maneuver.speed = mbs::Profile{{{0, 1.2}, {0.1, 0.6}}};
  wheel_loader::WheelLoader native(p, 0.0);
  for (int k = 0; k < 150; ++k) {
    ASSERT_EQ(set_wrench(f, wrench_at_step(k)), fmi2OK);
    ASSERT_EQ(lib.fmi2DoStep(f.c, k * kH, kH, fmi2True), fmi2OK) << f.log.all();
    const wheel_loader::Wrench w = wrench_at_step(k);
    native.set_wrench([w](double) { return w; });
    native.advance(static_cast<double>((k + 1) * 1000000LL) * 1e-9);
  }
  const auto a = fmu_outputs(f), b = native_outputs(native);
  EXPECT_TRUE(same_bits(a, b)) << first_difference(a, b);
  EXPECT_LT(a[19], 0.9) << "the amended maneuver slows the machine down";
}

TEST(WheelLoaderFmu, RepeatedStepsFromFmuStatesAreBitIdentical) {
  Library lib("wheel_loader");
  Instance f(lib, "wheel_loader");
  ASSERT_EQ(f.set("initial_position", 2.15), fmi2OK);
  ASSERT_EQ(f.initialize(0, 1), fmi2OK) << f.log.all();
  for (int k = 0; k < 50; ++k) {
    ASSERT_EQ(set_wrench(f, wrench_at_step(k)), fmi2OK);
    ASSERT_EQ(lib.fmi2DoStep(f.c, k * kH, kH, fmi2True), fmi2OK);
  }
  fmi2FMUstate s50 = nullptr;
  ASSERT_EQ(lib.fmi2GetFMUstate(f.c, &s50), fmi2OK) << f.log.all();
  auto run = [&](int from, int n, double scale) {
    std::vector<double> all;
    for (int k = from; k < from + n; ++k) {
      wheel_loader::Wrench w = wrench_at_step(k);
      for (auto& x : w.force) x *= scale;
      EXPECT_EQ(set_wrench(f, w), fmi2OK);
      EXPECT_EQ(lib.fmi2DoStep(f.c, k * kH, kH, fmi2False), fmi2OK) << f.log.all();
      const auto o = fmu_outputs(f);
      all.insert(all.end(), o.begin(), o.end());
    }
    return all;
  };
  const auto first = run(50, 30, 1.0);
  fmi2FMUstate s80 = nullptr;
  ASSERT_EQ(lib.fmi2GetFMUstate(f.c, &s80), fmi2OK);
  const auto after80 = run(80, 10, 1.0);
  ASSERT_EQ(lib.fmi2SetFMUstate(f.c, s50), fmi2OK) << f.log.all();
  const auto other = run(50, 30, 2.0);  // other inputs from the same state: other results
  EXPECT_FALSE(same_bits(first, other));
  ASSERT_EQ(lib.fmi2SetFMUstate(f.c, s50), fmi2OK);  // the same state twice
  EXPECT_TRUE(same_bits(first, run(50, 30, 1.0))) << "a repeated step differs";
  ASSERT_EQ(lib.fmi2SetFMUstate(f.c, s80), fmi2OK);  // forward again to a later state
  EXPECT_TRUE(same_bits(after80, run(80, 10, 1.0)));
  // The outputs right after a restore are those of the saved point.
  ASSERT_EQ(lib.fmi2SetFMUstate(f.c, s80), fmi2OK);
  EXPECT_TRUE(same_bits(fmu_outputs(f), std::vector<double>(first.end() - kNumOutputs, first.end())));
  // Stepping from a time the FMU is not at is refused with what to do.
  EXPECT_EQ(lib.fmi2DoStep(f.c, 0.5, kH, fmi2False), fmi2Error);
  EXPECT_NE(f.log.all().find("restore an FMU state"), std::string::npos) << f.log.all();
  lib.fmi2FreeFMUstate(f.c, &s50);
  lib.fmi2FreeFMUstate(f.c, &s80);
}

TEST(WheelLoaderFmu, BadParametersAndInputsAreRefusedByName) {
  Library lib("wheel_loader");
  struct Case {
    std::string name;  // parameter
    double value;
    std::string text;  // or a String parameter's value
    std::vector<std::string> expected;
  };
  const std::string missing = std::string(TEST_TMP_DIR) + "/no_such_machine.yaml";
  const std::vector<Case> cases{
      {"inner_step", -1e-4, "", {"parameter 'inner_step'", "must be > 0"}},
      {"inner_step", 1.00000001e-4, "", {"parameter 'inner_step'", "whole number of nanoseconds"}},
      {"inner_step", 0.01, "", {"parameter 'inner_step'", "at most 1e-3 s"}},
      {"gravity", -9.81, "", {"parameter 'gravity'", "must be >= 0"}},
      {"bucket.mass", 0, "", {"parameter 'bucket.mass'", "bucket.mass"}},
      {"ground.axle_damping", -1, "", {"parameter 'ground.axle_damping'", ">= 0"}},
      {"drive.traction_coefficient", 5, "", {"parameter 'drive.traction_coefficient'", "[0, 2]"}},
      {"initial_speed", 40, "", {"parameter 'initial_speed'", "at most 10 m/s"}},
      {"limits.max_force", -1, "", {"parameter 'limits.max_force'", "limits.max_force"}},
      {"machine_config", 0, missing, {"parameter 'machine_config'", "no_such_machine.yaml"}},
      {"machine_parameters", 0, "{gravty: 3}", {"machine_parameters", "gravty", "did you mean 'gravity'"}},
      {"machine_parameters", 0, "{gravity: [1, 2", {"parameter 'machine_parameters'"}},
      {"machine_parameters", 0, "{maneuver.lift: [[0, 5]]}", {"maneuver.lift", "beyond +-2 m"}},
      {"machine_parameters", 0, "{bucket: {j_pin: [0.9, -0.2]}, boom: {a_pin: [2.6, -0.27]}, bell_crank: {link_pin: [3.5, -0.47]}}",
       {"the machine cannot start", "tilt link"}},
  };
  for (const auto& c : cases) {
    Instance f(lib, "wheel_loader", "bad");
    ASSERT_NE(f.c, nullptr);
    if (c.name == "machine_config" || c.name == "machine_parameters")
      ASSERT_EQ(f.set_string(c.name, c.text), fmi2OK);
    else
      ASSERT_EQ(f.set(c.name, c.value), fmi2OK) << c.name;
    EXPECT_EQ(f.initialize(0, 1), fmi2Error) << c.name << " " << c.value << c.text;
    if (std::getenv("FMU_TEST_PRINT")) std::printf("%s", f.log.all().c_str());
    for (const auto& e : c.expected)
      EXPECT_NE(f.log.all().find(e), std::string::npos) << c.name << ": expected '" << e << "' in\n" << f.log.all();
  }
  {  // a number that is not finite is refused when set (the framework's check)
    Instance f(lib, "wheel_loader", "nan");
    EXPECT_EQ(f.set("gravity", NAN), fmi2Error);
    EXPECT_NE(f.log.all().find("gravity"), std::string::npos) << f.log.all();
  }
  // Steps and inputs.
  Instance f(lib, "wheel_loader", "inputs");
  ASSERT_EQ(f.initialize(0, 1), fmi2OK) << f.log.all();
  EXPECT_EQ(lib.fmi2DoStep(f.c, 0, 2.5e-4, fmi2True), fmi2Error);
  EXPECT_NE(f.log.all().find("not a multiple of the inner step 100000 ns (parameter 'inner_step')"), std::string::npos)
      << f.log.all();
  Instance g(lib, "wheel_loader", "force");
  ASSERT_EQ(g.initialize(0, 1), fmi2OK);
  ASSERT_EQ(g.set("force_x", -6e6), fmi2OK);
  EXPECT_EQ(lib.fmi2DoStep(g.c, 0, kH, fmi2True), fmi2Error);
  EXPECT_NE(g.log.all().find("exceeds parameter 'limits.max_force' = 5000000 N"), std::string::npos) << g.log.all();
  Instance h(lib, "wheel_loader", "torque");
  ASSERT_EQ(h.initialize(0, 1), fmi2OK);
  // 1e5 N about a point 300 m away: a torque of 3e7 N m about the bucket, above max_torque
  ASSERT_EQ(h.set("force_z", 1e5), fmi2OK);
  ASSERT_EQ(h.set("reference_point_x", 300), fmi2OK);
  EXPECT_EQ(lib.fmi2DoStep(h.c, 0, kH, fmi2True), fmi2Error);
  EXPECT_NE(h.log.all().find("limits.max_torque"), std::string::npos) << h.log.all();
  Instance n(lib, "wheel_loader", "nan");
  ASSERT_EQ(n.initialize(0, 1), fmi2OK);
  EXPECT_EQ(n.set("torque_y", NAN), fmi2Error);  // refused when set, the instance stays usable
  EXPECT_NE(n.log.all().find("torque_y"), std::string::npos) << n.log.all();
  EXPECT_EQ(lib.fmi2DoStep(n.c, 0, kH, fmi2True), fmi2OK) << n.log.all();
}

// Under cosim_master over LCM: the replay test's soil run (configs/wheel_loader.yaml, 1900
// spheres dropped in front of the machine, the bucket entering them) is recorded once with
// wheel_loader_adapter; then the loader runs as the FMU in fmu_adapter against the recorded
// soil (docs/replay.md: no DEM process, every request to the soil compared with the recorded
// one). The FMU integrates the same way, so the record is the native one bit for bit.
TEST(WheelLoaderFmu, UnderCosimMasterAgainstASoilRunTheRecordIsTheNativeAdaptersBitForBit) {
  replay_harness::ScopedEnv file("COSIM_KEY_FILE", ""), key("COSIM_KEY", "");
  const std::string mesh = std::string(BIN_DIR) + "/../meshes/bucket_r1.stl";
  const std::vector<std::string> soil{
      "--set", "time.end=0.4",
      "--set",
      "participants.soil.launch=[dem_service, " + harness::source("configs/soil/pile.yaml") +
          ", --set, 'tools.0.mesh=" + mesh + "', --set, scene.threads=1, --set, "
          "'particles={fill: [{species: grain, min: [6.6, -1.9, 0], max: [8.4, 1.9, 1.6], count: 1900, seed: 5}]}']",
      "--set", "participants.soil.parameters={output.file: ''}"};
  auto with = [&](std::vector<std::string> a) {
    a.insert(a.begin(), soil.begin(), soil.end());
    return a;
  };
  const std::string a = harness::temp_path("_wl_native.h5"), log = harness::temp_path("_wl_native.lcmlog");
  ASSERT_EQ(replay_harness::run_cosim_master("configs/wheel_loader.yaml", a,
                                             with({"--set", "participants.loader.parameters={initial_position: 2.15}",
                                                   "--record", log}),
                                             300),
            0)
      << harness::read_text(a + ".log");
  const auto wrench = harness::read_dataset(a, "participants/soil/outputs/bucket");
  ASSERT_EQ(wrench.size(), 9u * 401);
  double peak = 0;
  int pushing = 0;
  for (std::size_t r = 0; r < 401; ++r) {
    const double F = std::hypot(wrench[9 * r], wrench[9 * r + 1], wrench[9 * r + 2]);
    peak = std::max(peak, F);
    pushing += F > 100 ? 1 : 0;
  }
  std::printf("soil force above 100 N in %d of 400 steps, peak %.0f N\n", pushing, peak);
  EXPECT_GT(pushing, 100);  // the FMU has real soil wrenches to take
  EXPECT_GT(peak, 2e3);

  const std::string b = harness::temp_path("_wl_fmu.h5");
  ASSERT_EQ(replay_harness::run_cosim_master(
                "configs/wheel_loader_fmu.yaml", b,
                with({"--set", "participants.loader.parameters.fmu=" + std::string(FMU_DIR) + "/wheel_loader.fmu",
                      "--set", "participants.loader.parameters.start.initial_position=2.15", "--replay", log,
                      "--replay-side", "loader"}),
                300),
            0)
      << harness::read_text(b + ".log");
  const std::string blog = harness::read_text(b + ".log");
  EXPECT_EQ(blog.find("dem_service"), std::string::npos) << blog;
  EXPECT_EQ(replay_harness::number(b, "replay/diverged"), 0) << blog;
  int compared = 0;
  for (const char* ds :
       {"time", "participants/loader/outputs/bucket", "participants/loader/outputs/a_long",
        "participants/loader/outputs/a_vert", "participants/loader/outputs/j_long",
        "participants/loader/outputs/j_vert", "participants/loader/outputs/lift_force",
        "participants/loader/outputs/tilt_force", "participants/loader/outputs/speed",
        "participants/loader/outputs/x_machine", "participants/loader/outputs/drive_force",
        "participants/loader/outputs/normal_load", "participants/loader/outputs/bucket_pitch",
        "participants/loader/outputs/boom_angle", "participants/loader/outputs/edge_x",
        "participants/loader/outputs/edge_z", "participants/soil/outputs/bucket", "connections/soil.bucket/sent",
        "connections/loader.bucket_wrench/sent", "power/bucket/residual"}) {
    const auto x = harness::read_dataset(a, ds), y = harness::read_dataset(b, ds);
    EXPECT_GE(x.size(), 401u) << ds;
    EXPECT_TRUE(replay_harness::bit_identical(x, y)) << ds;
    compared += replay_harness::bit_identical(x, y) ? 1 : 0;
  }
  EXPECT_EQ(compared, 20);
  EXPECT_EQ(replay_harness::text(b, "status"), "finished");
  double requests = 0;
  for (double n : harness::read_dataset(a, "timing/iterations")) requests += n;
  EXPECT_GT(requests, 400);  // start-up iterations: repeated steps through FMU states
  EXPECT_EQ(replay_harness::number(b, "replay/requests_compared"), requests);
}

// fmu_adapter's mapping of the FMU's wrench input: the reference point as three FMU inputs (the
// FMU takes the point with the wrench) must name all three; one input mixed with outputs or a
// null is refused at start with the key, before any run.
TEST(WheelLoaderFmu, AReferencePointOfFmuInputsMustNameAllThree) {
  const std::string fmu = std::string(FMU_DIR) + "/wheel_loader.fmu";
  auto adapter = [&](const std::string& point, const std::string& tag) {
    const std::string mapping = harness::temp_path("_" + tag + ".yaml"), log = mapping + ".log";
    std::FILE* f = std::fopen(mapping.c_str(), "w");
    std::fprintf(f,
                 "inputs:\n  - name: bucket_wrench\n    wrench: {force: [force_x, force_y, force_z], "
                 "torque: [torque_x, torque_y, torque_z], frame: ground, reference_point: %s}\n"
                 "outputs:\n  - {name: speed, scalar: speed}\n",
                 point.c_str());
    std::fclose(f);
    harness::Process p = harness::spawn({harness::bin("fmu_adapter"), fmu, "--mapping", mapping, "--name", "wl",
                                         "--bus", harness::bus_url()},
                                        log);
    const int code = harness::wait_for(p, 60);
    return std::pair<int, std::string>(code, harness::read_text(log));
  };
  const auto mixed = adapter("[reference_point_x, position_y, reference_point_z]", "mixed");
  EXPECT_EQ(mixed.first, 2) << mixed.second;
  EXPECT_NE(mixed.second.find("inputs.0.wrench.reference_point.1: 'position_y' has causality output"),
            std::string::npos)
      << mixed.second;
  const auto partial = adapter("[reference_point_x, null, reference_point_z]", "partial");
  EXPECT_EQ(partial.first, 2) << partial.second;
  EXPECT_NE(partial.second.find("inputs.0.wrench.reference_point.1: a reference point set as FMU inputs needs all three"),
            std::string::npos)
      << partial.second;
}
