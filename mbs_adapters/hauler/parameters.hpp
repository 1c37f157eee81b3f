// Parameters of the articulated-hauler model (A40 class defaults, ../shared/facts.md
// "Machines"; docs/hauler.md has the table with sources and estimates).
// Planar in the x-z plane (x forward, y left, z up). Points of the front unit, the rear frame
// and the axles are [x, z] in CHASSIS coordinates: origin at the front axle centre at ride
// height (every strut at its ride stroke) with the body lowered, x forward, z up. Dump-body
// quantities are [x, z] in the BODY frame: origin on the hinge axis at the centre plane, x
// forward along the floor, z up from the floor when lowered.
// Every default here is also written out in configs/hauler/machine.yaml.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "machine_config.hpp"
#include "profile.hpp"

namespace hauler {

using mbs::Vec2;  // [x, z]
using mbs::Vec3;
// mass, com (chassis coordinates; the dump body's in the body frame), inertia
using mbs::Body;

struct Axle {
  double x = 0;           // chassis x of the axle centre (all axle centres lie on chassis z = 0)
  double mass = 2000;     // unsprung: axle, final drives, two wheels [kg]
  Vec3 inertia{1500, 400, 1500};
  MBS_DEFAULT_EQ(Axle)
};

// The dump body's inner shell in the body frame (shared by the model and the mesh generator):
// floor at z = floor_z from the open tail x = tail_x to the front wall x = tail_x + length,
// side walls at y = +-width/2, all walls side_height high above the floor.
struct BodyShape {
  double tail_x = -0.4;
  double floor_z = 0.25;
  double length = 5.5;
  double width = 3.0;
  double side_height = 1.5;
  double front_x() const { return tail_x + length; }
  double volume() const { return length * width * side_height; }
  MBS_DEFAULT_EQ(BodyShape)
};

// One hydro-pneumatic circuit: the struts of its axles (one lumped strut per axle for the
// two of a real axle) and their shared gas accumulator. Gas: p V^n = p_pre V_acc^n.
struct Circuit {
  double piston_area = 0.0157;         // per axle (two 100 mm bores) [m2]
  double accumulator_volume = 8e-3;    // gas volume at the precharge pressure [m3]
  double precharge = 3e6;              // [Pa]
  double polytropic = 1.35;            // n
  double damping_quadratic = 2e6;      // orifice: F = c2 v|v| [N s2/m2] per axle
  double damping_linear = 1.5e5;       // F = c1 v [N s/m] per axle
  double level_rate = 2e-4;            // oil flow of the ride-height control [m3/s]
  MBS_DEFAULT_EQ(Circuit)
};

struct Suspension {
  double stroke = 0.20;                // usable stroke [m]: 0 = fully compressed
  double ride_stroke = 0.10;           // ride height (target of the level control) [m]
  double end_stop_stiffness = 5e7;     // [N/m]
  double end_stop_damping = 5e5;       // [N s/m], only while in the stop
  Circuit front{};
  Circuit rear{0.0157, 12e-3, 2.5e6, 1.35, 2e6, 1.5e5, 4e-4};  // rear1 + rear2 (hydraulic bogie)
  bool level_control = true;
  double dead_band = 0.02;             // |ride - ride_stroke| tolerated [m]
  double time_constant = 1.0;          // low-pass of the measured ride height [s]
  MBS_DEFAULT_EQ(Suspension)
};

struct Tires {
  double unloaded_radius = 0.89;       // 29.5R25 [m]
  double stiffness = 2.5e6;            // radial, per axle (two tires) [N/m]
  double damping = 3e4;                // per axle [N s/m]
  MBS_DEFAULT_EQ(Tires)
};

// Longitudinal law: with the parking brake applied the wheels are locked to their axles and
// the contact patch is held by a stiff regularised friction (a spring-damper to where the
// brake was applied, capped at friction * vertical load); released, the wheels roll freely.
struct Brake {
  bool applied = true;
  double stiffness = 3e6;              // per axle [N/m]
  double damping = 1e5;                // per axle [N s/m]
  double friction = 0.7;               // cap, times the vertical load
  double rolling_radius = 0.8;         // lever of the locked wheel's contact point [m]
  MBS_DEFAULT_EQ(Brake)
};

struct Hoist {
  Vec2 frame_pin{-3.3, 0.1};           // chassis (rear frame)
  Vec2 body_pin{3.2, -0.15};           // body frame
  double stiffness = 1e8;              // position servo [N/m]
  double damping = 2e6;                // rate feedback [N s/m]
  MBS_DEFAULT_EQ(Hoist)
};

// Keyframed signals of time (mbs_adapters/common/profile.hpp).
using Profile = mbs::Profile;

struct Tipping {
  bool smooth = true;
  bool by_length = false;  // keyframes are hoist cylinder lengths [m], else body angles [deg]
  Profile profile;         // angle [deg] (stored as given) or length [m]
  MBS_DEFAULT_EQ(Tipping)
};

// A rigid load fixed in the dump body (body frame), e.g. a test payload.
struct Load {
  double mass = 0;
  Vec2 com{2.6, 1.1};
  double gyration_radius = 1.0;  // its own inertia m r^2 about each axis through com [m]
  MBS_DEFAULT_EQ(Load)
};

struct Parameters {
  double inner_step = 2e-4;        // s, fixed step of the explicit integrator (RK3)
  double gravity = 9.81;           // m/s2
  double initial_position = 0.0;   // world x of the front axle centre at t_start [m]

  Body front_unit{13000, {-0.3, 0.9}, {9000, 26000, 24000}};
  Body rear_frame{5500, {-5.0, 0.5}, {3500, 16000, 15000}};
  Axle front_axle{0.0, 2200, {1600, 500, 1600}};
  Axle rear1_axle{-4.7, 1900, {1400, 450, 1400}};
  Axle rear2_axle{-6.7, 1900, {1400, 450, 1400}};
  Tires tires;
  Brake brake;
  Suspension suspension;
  Body dump_body{6500, {2.4, 0.7}, {9000, 17000, 16000}};  // com in the body frame
  Vec2 hinge{-7.2, 1.25};                                    // chassis
  BodyShape shape;
  Hoist hoist;
  Tipping tipping = default_tipping();
  // The soil load the static start assumes (the DEM's settled payload, as gravity on a point
  // of the body); it is not applied after t_start: the body wrench is.
  Load static_load{};
  // A rigid payload fixed in the body for tests without DEM; reported as payload_rigid.
  std::optional<Load> test_payload;

  // sanity limits on the external wrench (an input above them is refused)
  double max_force = 5e6;    // N
  double max_torque = 3e7;   // N m, about the body origin

  const Axle& axle(int i) const { return i == 0 ? front_axle : i == 1 ? rear1_axle : rear2_axle; }
  static Tipping default_tipping();
  MBS_DEFAULT_EQ(Parameters)
};

// Reads and validates a machine config (the layout of configs/hauler/machine.yaml): unknown
// keys, wrong types and bad values raise cosim::config::ConfigError naming the dotted key
// and what is allowed. Keys left out keep the defaults above.
Parameters read_parameters(const YAML::Node& root, const std::string& path = "");
// Only the body shape (for the mesh generator): `shape` is a machine config's dump_body.shape.
BodyShape read_shape(const YAML::Node& shape, const std::string& path);

}  // namespace hauler
