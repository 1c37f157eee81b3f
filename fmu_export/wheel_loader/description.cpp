// The wheel-loader FMU's interface (docs/fmi.md, "The wheel-loader FMU"): the soil's wrench on
// the bucket in, the bucket's pose and twist and the native adapter's scalar reports out, the
// machine config's scalars as parameters with the native defaults (wheel_loader::Parameters).
#include "../common/description.hpp"

#include "table.hpp"

namespace fmu_export {

namespace wl {

const std::vector<ScalarOutput>& scalar_outputs() {
  // The names, order and meaning of wheel_loader_adapter's scalar outputs (wheel_loader_adapter.cpp).
  static const std::vector<ScalarOutput> v{
      {"a_long", "N", "A-pin force on the bucket from the boom, bucket x", true},
      {"a_vert", "N", "A-pin force on the bucket from the boom, bucket z", true},
      {"j_long", "N", "J-pin force on the bucket from the tilt link, bucket x", true},
      {"j_vert", "N", "J-pin force on the bucket from the tilt link, bucket z", true},
      {"lift_force", "N", "lift cylinder force, positive pushing", false},
      {"tilt_force", "N", "tilt cylinder force, positive pushing", false},
      {"speed", "m/s", "front axle centre, dx/dt", false},
      {"x_machine", "m", "front axle centre, x in ground", false},
      {"drive_force", "N", "traction at the tires", false},
      {"normal_load", "N", "sum of the axle loads", false},
      {"bucket_pitch", "rad", "angle of the bucket's x axis above the ground's x", false},
      {"boom_angle", "rad", "boom angle from its design pose", false},
      {"edge_x", "m", "cutting edge, x in ground", false},
      {"edge_z", "m", "cutting edge, z in ground", false},
  };
  return v;
}

const std::vector<ScalarParameter>& scalar_parameters() {
  static const std::vector<ScalarParameter> v = [] {
    const wheel_loader::Parameters p;  // the native defaults
    fmi2ValueReference vr = 200;
    std::vector<ScalarParameter> out;
    auto add = [&](const std::string& key, double value, const std::string& unit, const std::string& what) {
      out.push_back({key, vr++, value, unit, what});
    };
    add("inner_step", p.inner_step, "s",
        "fixed step of the explicit integrator (RK3); the communication step must be a multiple of it");
    add("gravity", p.gravity, "m/s2", "gravitational acceleration, pointing down");
    add("initial_position", p.initial_position, "m", "world x of the front axle centre at the start time");
    add("initial_speed", p.initial_speed, "m/s", "machine speed at the start time");
    add("ground.wheelbase", p.wheelbase, "m", "front to rear axle");
    add("ground.tire_radius", p.tire_radius, "m", "unloaded tire radius");
    add("ground.axle_stiffness", p.axle_stiffness, "N/m", "vertical stiffness per axle");
    add("ground.axle_damping", p.axle_damping, "N.s/m", "vertical damping per axle");
    add("drive.traction_coefficient", p.traction_coefficient, "", "drive force limit over the axle loads");
    add("drive.speed_gain", p.speed_gain, "1/s", "speed controller gain");
    add("frame.mass", p.frame.mass, "kg", "front and rear frame");
    add("boom.mass", p.boom.mass, "kg", "boom");
    add("bell_crank.mass", p.bell_crank.mass, "kg", "bell crank");
    add("tilt_link.mass", p.tilt_link.mass, "kg", "tilt link");
    add("bucket.mass", p.bucket.mass, "kg", "bucket");
    add("lift_cylinder.stiffness", p.lift_cylinder.stiffness, "N/m", "lift cylinder position feedback");
    add("lift_cylinder.damping", p.lift_cylinder.damping, "N.s/m", "lift cylinder rate feedback");
    add("tilt_cylinder.stiffness", p.tilt_cylinder.stiffness, "N/m", "tilt cylinder position feedback");
    add("tilt_cylinder.damping", p.tilt_cylinder.damping, "N.s/m", "tilt cylinder rate feedback");
    add("limits.max_force", p.max_force, "N", "a bucket force above this is refused (fmi2Error)");
    add("limits.max_torque", p.max_torque, "N.m", "a bucket torque (about the bucket origin) above this is refused");
    return out;
  }();
  return v;
}

}  // namespace wl

namespace {
using C = Causality;
using V = Variability;

Description make() {
  Description d;
  d.model_identifier = "wheel_loader";
  d.model_name = "wheel_loader";
  d.description =
      "Wheel loader, L180 class (soilcosim, mbs_adapters/wheel_loader): planar Simbody model with Z-bar "
      "linkage, tires, drive and a prescribed maneuver; input the soil's wrench on the bucket, outputs the "
      "bucket's pose and twist (docs/wheel_loader.md, docs/fmi.md)";
  d.can_get_and_set_state = true;
  d.can_interpolate_inputs = false;  // the wrench is held over each doStep, as the native adapter
                                     // under the paper's constant force predictor
  d.default_start = 0;
  d.default_stop = 15;
  d.default_step = 1e-3;
  const char* axes[] = {"x", "y", "z"};
  auto var = [&](const std::string& name, fmi2ValueReference vr, C c, double start, const std::string& unit,
                 const std::string& what, std::vector<std::string> deps = {}) {
    d.variables.push_back({name, Type::Real, vr, c, c == C::Parameter ? V::Fixed : V::Continuous, start, "", unit,
                           what, std::move(deps)});
  };
  std::vector<std::string> wrench_inputs;
  for (int a = 0; a < 3; ++a) {
    var(std::string("force_") + axes[a], wl::kForce + a, C::Input, 0, "N", "soil force on the bucket, ground axes");
    wrench_inputs.push_back(std::string("force_") + axes[a]);
  }
  for (int a = 0; a < 3; ++a) {
    var(std::string("torque_") + axes[a], wl::kTorque + a, C::Input, 0, "N.m",
        "soil torque on the bucket about reference_point, ground axes");
    wrench_inputs.push_back(std::string("torque_") + axes[a]);
  }
  for (int a = 0; a < 3; ++a) {
    var(std::string("reference_point_") + axes[a], wl::kPoint + a, C::Input, 0, "m",
        "the point the torque is about, ground");
    wrench_inputs.push_back(std::string("reference_point_") + axes[a]);
  }
  for (int a = 0; a < 3; ++a)
    var(std::string("position_") + axes[a], wl::kPosition + a, C::Output, 0, "m",
        "bucket frame origin (A-pin centre), ground");
  const char* q[] = {"w", "x", "y", "z"};
  for (int a = 0; a < 4; ++a)
    var(std::string("quaternion_") + q[a], wl::kQuaternion + a, C::Output, 0, "",
        "unit quaternion (w, x, y, z) of the bucket frame, body -> ground");
  for (int a = 0; a < 3; ++a)
    var(std::string("velocity_") + axes[a], wl::kVelocity + a, C::Output, 0, "m/s",
        "velocity of the bucket frame origin, ground");
  for (int a = 0; a < 3; ++a)
    var(std::string("angular_velocity_") + axes[a], wl::kAngularVelocity + a, C::Output, 0, "rad/s",
        "angular velocity of the bucket, ground axes");
  fmi2ValueReference vr = wl::kScalars;
  for (const auto& s : wl::scalar_outputs())
    var(s.name, vr++, C::Output, 0, s.unit, s.description, s.feedthrough ? wrench_inputs : std::vector<std::string>{});
  for (const auto& p : wl::scalar_parameters())
    var(p.key, p.vr, C::Parameter, p.native_default, p.unit,
        p.description + " (machine config key " + p.key + "; left at this default, the machine_config file's value applies)");
  d.variables.push_back({"machine_config", Type::String, wl::kMachineConfig, C::Parameter, V::Fixed, 0, "", "",
                         "machine config YAML (configs/wheel_loader/machine.yaml layout); empty: the built-in "
                         "defaults (equal to that file); a relative path is taken from the working directory",
                         {}});
  d.variables.push_back({"machine_parameters", Type::String, wl::kMachineParameters, C::Parameter, V::Fixed, 0, "",
                         "",
                         "YAML map of dotted keys amending machine_config, as the master's "
                         "participants.<name>.parameters amend wheel_loader_adapter's file: "
                         "{maneuver.tilt: [[0, 0], [2, 0.1]]}",
                         {}});
  return d;
}
}  // namespace

const Description& description() {
  static const Description d = make();
  return d;
}

}  // namespace fmu_export
