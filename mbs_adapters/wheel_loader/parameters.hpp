// Parameters of the wheel-loader model (L180 class defaults, ../shared/facts.md "Machines").
// Planar linkage in the x-z plane (x forward, y left, z up). Pin positions of the linkage are
// given in the FRAME's coordinates [x, z] at the design pose (boom lowered, bucket flat):
// origin at the front axle centre, x forward, z up. Bucket quantities are in the BUCKET frame
// (origin at the A-pin, x along the floor towards the cutting edge, z up from the floor).
// Every default here is also written out in configs/wheel_loader/machine.yaml.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <string>
#include <vector>

#include "machine_config.hpp"
#include "profile.hpp"

namespace wheel_loader {

using mbs::Vec2;  // [x, z]
using mbs::Vec3;
// mass, com (frame coordinates at the design pose; the bucket's in the bucket frame), inertia
using mbs::Body;

// The bucket's shell in the bucket frame (shared by the model and the mesh generator).
struct BucketShape {
  double width = 3.0;         // outer width, side plates at y = +-width/2
  double edge_x = 1.65;       // cutting-edge tip, x
  double floor_z = -0.45;     // bottom plate plane, z (cutting edge tip lies on it)
  double back_x = 0.2;        // back plate plane, x
  double heel_radius = 0.45;  // arc joining bottom and back plates
  double back_top_z = 0.85;   // top of the back plate, z
  double guard_length = 0.3;  // spill guard, leaning forward from the top of the back plate
  double guard_angle = 40;    // spill guard angle above the horizontal [deg]
  double edge_depth = 0.25;   // cutting-edge bevel: reaches this far back under the floor
  double edge_thickness = 0.06;  // and this far below it
  MBS_DEFAULT_EQ(BucketShape)
};

// Keyframed signals of time (mbs_adapters/common/profile.hpp).
using Profile = mbs::Profile;

struct Maneuver {
  bool smooth = true;
  Profile speed;  // target machine speed [m/s]
  Profile lift;   // lift cylinder extension from its design-pose length [m]
  Profile tilt;   // tilt cylinder extension from its design-pose length [m] (+ curls back)
  MBS_DEFAULT_EQ(Maneuver)
};

struct Cylinder {
  Vec2 frame_pin{0, 0};   // frame coordinates
  double stiffness = 1e8;  // N/m: position feedback (hydraulic compliance)
  double damping = 1e6;    // N s/m: rate feedback
  MBS_DEFAULT_EQ(Cylinder)
};

struct Parameters {
  double inner_step = 1e-4;        // s, fixed step of the explicit integrator
  double gravity = 9.81;           // m/s2
  double initial_position = 0.0;   // world x of the front axle centre at t_start [m]
  double initial_speed = 1.2;      // m/s at t_start

  // ground contact: one vertical spring-damper per axle (two tires), contact at z = 0
  double wheelbase = 3.55;
  double tire_radius = 0.85;
  double axle_stiffness = 2.4e6;
  double axle_damping = 3.5e4;
  // drive: F = clamp(speed_gain * total_mass * (v_target - v), +-traction_coefficient * N)
  double traction_coefficient = 0.6;
  double speed_gain = 10.0;  // 1/s

  Body frame{20350, {-2.73, 0.35}, {23900, 93700, 96400}};
  Body boom{3300, {1.1, 0.55}, {1300, 3500, 4000}};
  Vec2 boom_pivot{-0.35, 1.35};
  Vec2 a_pin{2.6, -0.27};
  Vec2 lift_boom_pin{0.774, 0.297};
  Vec2 crank_pivot{1.607, 0.74};
  Body bell_crank{600, {1.6, 0.8}, {90, 90, 15}};
  Vec2 crank_cylinder_pin{1.407, 1.49};
  Vec2 crank_link_pin{1.857, 0.19};
  Body tilt_link{150, {0, 0}, {7, 7, 1}};  // com: midpoint of its pins (not a parameter)
  Body bucket{2600, {0.83, -0.06}, {2500, 1100, 2700}};  // com in the bucket frame
  Vec2 j_pin{0.0, 0.62};                                  // bucket frame
  BucketShape shape;
  Cylinder lift_cylinder{{-0.9, -0.1}, 2e8, 3e6};
  Cylinder tilt_cylinder{{-0.6, 1.75}, 1e8, 1e6};

  Maneuver maneuver = default_maneuver();

  // sanity limits on the external wrench (an input above them is refused)
  double max_force = 5e6;    // N
  double max_torque = 2e7;   // N m

  static Maneuver default_maneuver();
  MBS_DEFAULT_EQ(Parameters)
};

// Reads and validates a machine config (the layout of configs/wheel_loader/machine.yaml):
// unknown keys, wrong types and bad values raise cosim::config::ConfigError naming the dotted
// key (prefixed with `path` when given). Keys left out keep the defaults above.
Parameters read_parameters(const YAML::Node& root, const std::string& path = "");
// Only the bucket shape (for the mesh generator): root is a machine config.
BucketShape read_shape(const YAML::Node& shape, const std::string& path);

}  // namespace wheel_loader
