#include "parameters.hpp"

#include <cosim/yaml_config.hpp>

#include <algorithm>
#include <cmath>

namespace wheel_loader {

namespace cfg = cosim::config;
using cfg::ConfigError;
using cfg::join_path;
using mbs::get_vec2;
using mbs::read_body;

namespace {

Profile read_profile(const YAML::Node& n, const std::string& parent, const std::string& key,
                     const Profile& fallback) {
  return n[key] ? mbs::read_profile(n, parent, key) : fallback;
}

}  // namespace

Maneuver Parameters::default_maneuver() {
  Maneuver m;
  m.smooth = true;
  // approach at 1.2 m/s, keep pushing while filling, slow down for the breakout
  m.speed.knots = {{0, 1.2}, {10, 1.2}, {13, 0.3}, {15, 0.0}};
  // boom held low through the penetration, lifted from 4 s, breakout lift to 15 s
  m.lift.knots = {{0, 0.0}, {4, 0.0}, {12, 0.25}, {15, 0.45}};
  // five tilt pulses between 2 and 9 s (about 8 deg each)
  m.tilt.knots = {{0, 0.0},    {2.0, 0.0},  {2.6, 0.08}, {3.4, 0.08}, {4.0, 0.16},
                  {4.8, 0.16}, {5.4, 0.24}, {6.2, 0.24}, {6.8, 0.32}, {7.6, 0.32},
                  {8.4, 0.40}};
  return m;
}

BucketShape read_shape(const YAML::Node& n, const std::string& path) {
  BucketShape s;
  cfg::check_keys(n, path, {"width", "edge_x", "floor_z", "back_x", "heel_radius", "back_top_z",
                            "guard_length", "guard_angle", "edge_depth", "edge_thickness"});
  s.width = cfg::get_positive_or(n, path, "width", s.width);
  s.edge_x = cfg::get_double_or(n, path, "edge_x", s.edge_x);
  s.floor_z = cfg::get_double_or(n, path, "floor_z", s.floor_z);
  s.back_x = cfg::get_double_or(n, path, "back_x", s.back_x);
  s.heel_radius = cfg::get_positive_or(n, path, "heel_radius", s.heel_radius);
  s.back_top_z = cfg::get_double_or(n, path, "back_top_z", s.back_top_z);
  s.guard_length = cfg::get_double_or(n, path, "guard_length", s.guard_length);
  s.guard_angle = cfg::get_double_or(n, path, "guard_angle", s.guard_angle);
  s.edge_depth = cfg::get_positive_or(n, path, "edge_depth", s.edge_depth);
  s.edge_thickness = cfg::get_positive_or(n, path, "edge_thickness", s.edge_thickness);
  if (s.edge_x - s.back_x < s.heel_radius + 0.05)
    throw ConfigError(join_path(path, "edge_x") +
                      ": the cutting edge must lie at least heel_radius + 0.05 m ahead of back_x");
  if (s.back_top_z - s.floor_z < s.heel_radius + 0.05)
    throw ConfigError(join_path(path, "back_top_z") +
                      ": the back plate must reach at least heel_radius + 0.05 m above floor_z");
  if (s.guard_length < 0) throw ConfigError(join_path(path, "guard_length") + ": must be >= 0");
  if (s.guard_angle < 0 || s.guard_angle > 90)
    throw ConfigError(join_path(path, "guard_angle") + ": must be in [0, 90] degrees");
  if (s.edge_depth >= s.edge_x - s.back_x - s.heel_radius)
    throw ConfigError(join_path(path, "edge_depth") +
                      ": must be shorter than the flat part of the floor (edge_x - back_x - heel_radius)");
  return s;
}

Parameters read_parameters(const YAML::Node& root, const std::string& path) {
  Parameters p;
  if (!root || root.IsNull()) return p;
  cfg::check_keys(root, path,
                  {"inner_step", "gravity", "initial_position", "initial_speed", "ground", "drive",
                   "frame", "boom", "bell_crank", "tilt_link", "bucket", "lift_cylinder",
                   "tilt_cylinder", "maneuver", "limits"});
  p.inner_step = cfg::get_positive_or(root, path, "inner_step", p.inner_step);
  if (p.inner_step > 1e-3)
    throw ConfigError(join_path(path, "inner_step") +
                      ": at most 1e-3 s (the stiff cylinders need about 1e-4 s)");
  p.gravity = cfg::get_double_or(root, path, "gravity", p.gravity);
  if (p.gravity < 0) throw ConfigError(join_path(path, "gravity") + ": must be >= 0 (m/s2, pointing down)");
  p.initial_position = cfg::get_double_or(root, path, "initial_position", p.initial_position);
  p.initial_speed = cfg::get_double_or(root, path, "initial_speed", p.initial_speed);
  if (std::abs(p.initial_speed) > 10)
    throw ConfigError(join_path(path, "initial_speed") + ": |speed| must be at most 10 m/s");

  if (root["ground"]) {
    const auto n = root["ground"];
    const auto gp = join_path(path, "ground");
    cfg::check_keys(n, gp, {"wheelbase", "tire_radius", "axle_stiffness", "axle_damping"});
    p.wheelbase = cfg::get_positive_or(n, gp, "wheelbase", p.wheelbase);
    p.tire_radius = cfg::get_positive_or(n, gp, "tire_radius", p.tire_radius);
    p.axle_stiffness = cfg::get_positive_or(n, gp, "axle_stiffness", p.axle_stiffness);
    p.axle_damping = cfg::get_double_or(n, gp, "axle_damping", p.axle_damping);
    if (p.axle_damping < 0) throw ConfigError(join_path(gp, "axle_damping") + ": must be >= 0");
  }
  if (root["drive"]) {
    const auto n = root["drive"];
    const auto dp = join_path(path, "drive");
    cfg::check_keys(n, dp, {"traction_coefficient", "speed_gain"});
    p.traction_coefficient = cfg::get_double_or(n, dp, "traction_coefficient", p.traction_coefficient);
    if (!(p.traction_coefficient >= 0 && p.traction_coefficient <= 2))
      throw ConfigError(join_path(dp, "traction_coefficient") + ": must be in [0, 2]");
    p.speed_gain = cfg::get_positive_or(n, dp, "speed_gain", p.speed_gain);
  }
  read_body(root, path, "frame", p.frame);
  read_body(root, path, "boom", p.boom, true, {"pivot", "a_pin", "lift_pin", "crank_pivot"});
  if (const auto n = root["boom"]) {
    const auto bp = join_path(path, "boom");
    p.boom_pivot = get_vec2(n, bp, "pivot", p.boom_pivot);
    p.a_pin = get_vec2(n, bp, "a_pin", p.a_pin);
    p.lift_boom_pin = get_vec2(n, bp, "lift_pin", p.lift_boom_pin);
    p.crank_pivot = get_vec2(n, bp, "crank_pivot", p.crank_pivot);
  }
  read_body(root, path, "bell_crank", p.bell_crank, true, {"cylinder_pin", "link_pin"});
  if (const auto n = root["bell_crank"]) {
    const auto bp = join_path(path, "bell_crank");
    p.crank_cylinder_pin = get_vec2(n, bp, "cylinder_pin", p.crank_cylinder_pin);
    p.crank_link_pin = get_vec2(n, bp, "link_pin", p.crank_link_pin);
  }
  read_body(root, path, "tilt_link", p.tilt_link, false);
  read_body(root, path, "bucket", p.bucket, true, {"j_pin", "shape"});
  if (const auto n = root["bucket"]) {
    const auto bp = join_path(path, "bucket");
    p.j_pin = get_vec2(n, bp, "j_pin", p.j_pin);
    if (n["shape"]) p.shape = read_shape(n["shape"], join_path(bp, "shape"));
  }
  for (auto [key, cyl] : {std::pair{"lift_cylinder", &p.lift_cylinder},
                          std::pair{"tilt_cylinder", &p.tilt_cylinder}}) {
    if (!root[key]) continue;
    const auto n = root[key];
    const auto cp = join_path(path, key);
    cfg::check_keys(n, cp, {"frame_pin", "stiffness", "damping"});
    cyl->frame_pin = get_vec2(n, cp, "frame_pin", cyl->frame_pin);
    cyl->stiffness = cfg::get_positive_or(n, cp, "stiffness", cyl->stiffness);
    cyl->damping = cfg::get_double_or(n, cp, "damping", cyl->damping);
    if (cyl->damping < 0) throw ConfigError(join_path(cp, "damping") + ": must be >= 0");
  }
  if (root["maneuver"]) {
    const auto n = root["maneuver"];
    const auto mp = join_path(path, "maneuver");
    cfg::check_keys(n, mp, {"interpolation", "speed", "lift", "tilt"});
    p.maneuver.smooth = cfg::get_choice(n, mp, "interpolation", {"smooth", "linear"}, "smooth") == "smooth";
    p.maneuver.speed = read_profile(n, mp, "speed", p.maneuver.speed);
    p.maneuver.lift = read_profile(n, mp, "lift", p.maneuver.lift);
    p.maneuver.tilt = read_profile(n, mp, "tilt", p.maneuver.tilt);
    for (const auto& k : p.maneuver.speed.knots)
      if (std::abs(k[1]) > 10) throw ConfigError(join_path(mp, "speed") + ": |speed| must be at most 10 m/s");
    for (auto [name, prof] : {std::pair{"lift", &p.maneuver.lift}, std::pair{"tilt", &p.maneuver.tilt}})
      for (const auto& k : prof->knots)
        if (std::abs(k[1]) > 2)
          throw ConfigError(join_path(mp, name) + ": cylinder extension " + std::to_string(k[1]) +
                            " m is beyond +-2 m");
  }
  mbs::read_limits(root, path, p.max_force, p.max_torque);
  return p;
}

}  // namespace wheel_loader
