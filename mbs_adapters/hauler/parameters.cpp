#include "parameters.hpp"

#include <cosim/yaml_config.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace hauler {

namespace cfg = cosim::config;
using cfg::ConfigError;
using cfg::join_path;
using mbs::get_vec2;
using mbs::get_vec3;

namespace {

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

double non_negative(const YAML::Node& n, const std::string& path, const std::string& key,
                    double fallback) {
  const double v = cfg::get_double_or(n, path, key, fallback);
  if (!(v >= 0)) throw ConfigError(join_path(path, key) + ": must be >= 0, got " + num(v));
  return v;
}

void read_axle(const YAML::Node& root, const std::string& parent, const std::string& key, Axle& a) {
  if (!root[key]) return;
  const YAML::Node n = root[key];
  const std::string path = join_path(parent, key);
  cfg::check_keys(n, path, {"x", "mass", "inertia"});
  a.x = cfg::get_double_or(n, path, "x", a.x);
  a.mass = cfg::get_positive_or(n, path, "mass", a.mass);
  a.inertia = get_vec3(n, path, "inertia", a.inertia);
  mbs::check_inertia(a.inertia, path);
}

void read_circuit(const YAML::Node& root, const std::string& parent, const std::string& key,
                  Circuit& c) {
  if (!root[key]) return;
  const YAML::Node n = root[key];
  const std::string path = join_path(parent, key);
  cfg::check_keys(n, path, {"piston_area", "accumulator_volume", "precharge", "polytropic",
                            "damping_quadratic", "damping_linear", "level_rate"});
  c.piston_area = cfg::get_positive_or(n, path, "piston_area", c.piston_area);
  if (c.piston_area > 0.5)
    throw ConfigError(join_path(path, "piston_area") + ": " + num(c.piston_area) +
                      " m2 is not a strut (m2, per axle: two 100 mm bores are 0.0157)");
  c.accumulator_volume = cfg::get_positive_or(n, path, "accumulator_volume", c.accumulator_volume);
  if (c.accumulator_volume > 1)
    throw ConfigError(join_path(path, "accumulator_volume") + ": " + num(c.accumulator_volume) +
                      " m3 is too large (the unit is m3: 8 litres are 8e-3)");
  c.precharge = cfg::get_positive_or(n, path, "precharge", c.precharge);
  c.polytropic = cfg::get_double_or(n, path, "polytropic", c.polytropic);
  if (!(c.polytropic >= 1.0 && c.polytropic <= 1.67))
    throw ConfigError(join_path(path, "polytropic") + ": " + num(c.polytropic) +
                      " is not a gas's polytropic exponent (allowed 1.0 isothermal .. 1.67; "
                      "nitrogen in an accumulator: 1.3-1.4)");
  c.damping_quadratic = non_negative(n, path, "damping_quadratic", c.damping_quadratic);
  c.damping_linear = non_negative(n, path, "damping_linear", c.damping_linear);
  c.level_rate = non_negative(n, path, "level_rate", c.level_rate);
}

Load read_load(const YAML::Node& n, const std::string& path, Load l, bool positive) {
  cfg::check_keys(n, path, {"mass", "com", "gyration_radius"});
  l.mass = positive ? cfg::get_positive(n, path, "mass") : non_negative(n, path, "mass", l.mass);
  l.com = get_vec2(n, path, "com", l.com);
  l.gyration_radius = cfg::get_positive_or(n, path, "gyration_radius", l.gyration_radius);
  return l;
}

}  // namespace

Tipping Parameters::default_tipping() {
  Tipping t;
  t.smooth = true;
  t.by_length = false;
  // lowered until 1 s, raised to 68 deg in 14 s, held 10 s, lowered in 10 s
  t.profile.knots = {{0, 0}, {1, 0}, {15, 68}, {25, 68}, {35, 0}};
  return t;
}

BodyShape read_shape(const YAML::Node& n, const std::string& path) {
  BodyShape s;
  cfg::check_keys(n, path, {"tail_x", "floor_z", "length", "width", "side_height"});
  s.tail_x = cfg::get_double_or(n, path, "tail_x", s.tail_x);
  s.floor_z = cfg::get_double_or(n, path, "floor_z", s.floor_z);
  s.length = cfg::get_positive_or(n, path, "length", s.length);
  s.width = cfg::get_positive_or(n, path, "width", s.width);
  s.side_height = cfg::get_positive_or(n, path, "side_height", s.side_height);
  if (s.length > 15 || s.width > 6 || s.side_height > 5)
    throw ConfigError(path + ": length " + num(s.length) + ", width " + num(s.width) +
                      ", side_height " + num(s.side_height) +
                      " m is not a hauler body (at most 15, 6 and 5 m)");
  if (!(s.front_x() > 0))
    throw ConfigError(join_path(path, "length") +
                      ": the front wall (tail_x + length) must lie ahead of the hinge (x > 0)");
  if (std::abs(s.tail_x) > 2 || std::abs(s.floor_z) > 2)
    throw ConfigError(path + ": tail_x and floor_z place the shell relative to the hinge axis and "
                             "must be within 2 m of it");
  return s;
}

Parameters read_parameters(const YAML::Node& root, const std::string& path) {
  Parameters p;
  if (!root || root.IsNull()) return p;
  cfg::check_keys(root, path,
                  {"inner_step", "gravity", "initial_position", "front_unit", "rear_frame", "axles",
                   "tires", "brake", "suspension", "dump_body", "hoist", "tipping", "static_load",
                   "test_payload", "limits"});
  p.inner_step = cfg::get_positive_or(root, path, "inner_step", p.inner_step);
  if (p.inner_step > 1e-3)
    throw ConfigError(join_path(path, "inner_step") +
                      ": at most 1e-3 s (the end stops and the hoist servo need about 2e-4 s)");
  p.gravity = non_negative(root, path, "gravity", p.gravity);
  p.initial_position = cfg::get_double_or(root, path, "initial_position", p.initial_position);

  mbs::read_body(root, path, "front_unit", p.front_unit);
  mbs::read_body(root, path, "rear_frame", p.rear_frame);
  if (root["axles"]) {
    const auto n = root["axles"];
    const auto ap = join_path(path, "axles");
    cfg::check_keys(n, ap, {"front", "rear1", "rear2"});
    read_axle(n, ap, "front", p.front_axle);
    read_axle(n, ap, "rear1", p.rear1_axle);
    read_axle(n, ap, "rear2", p.rear2_axle);
    if (!(p.rear1_axle.x < p.front_axle.x - 1.0))
      throw ConfigError(join_path(ap, "rear1.x") + ": " + num(p.rear1_axle.x) +
                        " must lie at least 1 m behind the front axle (x = " + num(p.front_axle.x) + ")");
    if (!(p.rear2_axle.x < p.rear1_axle.x - 0.5))
      throw ConfigError(join_path(ap, "rear2.x") + ": " + num(p.rear2_axle.x) +
                        " must lie at least 0.5 m behind rear1 (x = " + num(p.rear1_axle.x) + ")");
  }
  if (root["tires"]) {
    const auto n = root["tires"];
    const auto tp = join_path(path, "tires");
    cfg::check_keys(n, tp, {"unloaded_radius", "stiffness", "damping"});
    p.tires.unloaded_radius = cfg::get_positive_or(n, tp, "unloaded_radius", p.tires.unloaded_radius);
    if (p.tires.unloaded_radius > 2)
      throw ConfigError(join_path(tp, "unloaded_radius") + ": " + num(p.tires.unloaded_radius) +
                        " m is not a tire (a 29.5R25 is about 0.89 m)");
    p.tires.stiffness = cfg::get_positive_or(n, tp, "stiffness", p.tires.stiffness);
    p.tires.damping = non_negative(n, tp, "damping", p.tires.damping);
  }
  if (root["brake"]) {
    const auto n = root["brake"];
    const auto bp = join_path(path, "brake");
    cfg::check_keys(n, bp, {"applied", "stiffness", "damping", "friction", "rolling_radius"});
    p.brake.applied = cfg::get_bool_or(n, bp, "applied", p.brake.applied);
    p.brake.stiffness = cfg::get_positive_or(n, bp, "stiffness", p.brake.stiffness);
    p.brake.damping = non_negative(n, bp, "damping", p.brake.damping);
    p.brake.friction = cfg::get_double_or(n, bp, "friction", p.brake.friction);
    if (!(p.brake.friction > 0 && p.brake.friction <= 2))
      throw ConfigError(join_path(bp, "friction") + ": must be in (0, 2], got " + num(p.brake.friction));
    p.brake.rolling_radius = cfg::get_positive_or(n, bp, "rolling_radius", p.brake.rolling_radius);
  }
  if (p.brake.rolling_radius > p.tires.unloaded_radius)
    throw ConfigError(join_path(path, "brake.rolling_radius") + ": " + num(p.brake.rolling_radius) +
                      " m must not exceed tires.unloaded_radius (" + num(p.tires.unloaded_radius) + " m)");
  if (root["suspension"]) {
    const auto n = root["suspension"];
    const auto sp = join_path(path, "suspension");
    auto& s = p.suspension;
    cfg::check_keys(n, sp, {"stroke", "ride_stroke", "end_stop_stiffness", "end_stop_damping",
                            "front", "rear", "level_control"});
    s.stroke = cfg::get_positive_or(n, sp, "stroke", s.stroke);
    if (s.stroke > 1)
      throw ConfigError(join_path(sp, "stroke") + ": " + num(s.stroke) + " m is beyond 1 m");
    s.ride_stroke = cfg::get_double_or(n, sp, "ride_stroke", s.ride_stroke);
    s.end_stop_stiffness = cfg::get_positive_or(n, sp, "end_stop_stiffness", s.end_stop_stiffness);
    s.end_stop_damping = non_negative(n, sp, "end_stop_damping", s.end_stop_damping);
    read_circuit(n, sp, "front", s.front);
    read_circuit(n, sp, "rear", s.rear);
    if (n["level_control"]) {
      const auto l = n["level_control"];
      const auto lp = join_path(sp, "level_control");
      cfg::check_keys(l, lp, {"enabled", "dead_band", "time_constant"});
      s.level_control = cfg::get_bool_or(l, lp, "enabled", s.level_control);
      s.dead_band = non_negative(l, lp, "dead_band", s.dead_band);
      s.time_constant = cfg::get_positive_or(l, lp, "time_constant", s.time_constant);
    }
  }
  {
    const auto& s = p.suspension;
    const auto sp = join_path(path, "suspension");
    if (!(s.ride_stroke - s.dead_band > 0 && s.ride_stroke + s.dead_band < s.stroke))
      throw ConfigError(join_path(sp, "ride_stroke") + ": " + num(s.ride_stroke) +
                        " m with level_control.dead_band " + num(s.dead_band) +
                        " m must lie inside the stroke (0, " + num(s.stroke) + ") m");
  }
  mbs::read_body(root, path, "dump_body", p.dump_body, true, {"hinge", "shape"});
  if (root["dump_body"]) {
    const auto n = root["dump_body"];
    const auto bp = join_path(path, "dump_body");
    p.hinge = get_vec2(n, bp, "hinge", p.hinge);
    if (n["shape"]) p.shape = read_shape(n["shape"], join_path(bp, "shape"));
  }
  if (!(p.hinge[0] < p.rear2_axle.x))
    throw ConfigError(join_path(path, "dump_body.hinge") + ": x = " + num(p.hinge[0]) +
                      " must lie behind the rear axle (axles.rear2.x = " + num(p.rear2_axle.x) + ")");
  if (root["hoist"]) {
    const auto n = root["hoist"];
    const auto hp = join_path(path, "hoist");
    cfg::check_keys(n, hp, {"frame_pin", "body_pin", "stiffness", "damping"});
    p.hoist.frame_pin = get_vec2(n, hp, "frame_pin", p.hoist.frame_pin);
    p.hoist.body_pin = get_vec2(n, hp, "body_pin", p.hoist.body_pin);
    p.hoist.stiffness = cfg::get_positive_or(n, hp, "stiffness", p.hoist.stiffness);
    p.hoist.damping = non_negative(n, hp, "damping", p.hoist.damping);
  }
  if (root["tipping"]) {
    const auto n = root["tipping"];
    const auto tp = join_path(path, "tipping");
    cfg::check_keys(n, tp, {"interpolation", "mode", "angle", "length"});
    p.tipping.smooth = cfg::get_choice(n, tp, "interpolation", {"smooth", "linear"}, "smooth") == "smooth";
    p.tipping.by_length = cfg::get_choice(n, tp, "mode", {"angle", "length"}, "angle") == "length";
    // both lists may be present (a --set cannot remove the file's list); mode picks one, and
    // each present list is checked
    if (n["angle"]) {
      const Profile a = mbs::read_profile(n, tp, "angle");
      for (std::size_t i = 0; i < a.knots.size(); ++i) {
        const double v = a.knots[i][1];
        if (!(v >= 0 && v <= 80))
          throw ConfigError(join_path(tp, "angle") + "." + std::to_string(i) + ": body angle " +
                            num(v) + " deg must be in [0, 80] (degrees, 0 = lowered)");
      }
      if (!p.tipping.by_length) p.tipping.profile = a;
    }
    if (n["length"]) {
      const Profile l = mbs::read_profile(n, tp, "length");
      for (std::size_t i = 0; i < l.knots.size(); ++i)
        if (!(l.knots[i][1] > 0))
          throw ConfigError(join_path(tp, "length") + "." + std::to_string(i) +
                            ": cylinder lengths must be > 0 m");
      if (p.tipping.by_length) p.tipping.profile = l;
    } else if (p.tipping.by_length) {
      throw ConfigError(join_path(tp, "length") +
                        ": missing (mode: length needs keyframes [[t, hoist length m], ...])");
    }
  }
  if (root["static_load"])
    p.static_load = read_load(root["static_load"], join_path(path, "static_load"), p.static_load, false);
  if (root["test_payload"] && !root["test_payload"].IsNull())
    p.test_payload = read_load(root["test_payload"], join_path(path, "test_payload"), Load{}, true);
  mbs::read_limits(root, path, p.max_force, p.max_torque);
  return p;
}

}  // namespace hauler
