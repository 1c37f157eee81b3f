#include "wheel_loader_adapter.hpp"

using wheel_loader::Reports;
using wheel_loader::V3;

namespace mbs {

template <>
MachineAdapter::Settings wheel_loader::WheelLoaderAdapter::read(const YAML::Node& config) {
  p_ = wheel_loader::read_parameters(config);
  return {"bucket", p_.inner_step, p_.max_force, p_.max_torque,
          {"a_long", "a_vert", "j_long", "j_vert", "lift_force", "tilt_force", "speed", "x_machine",
           "drive_force", "normal_load", "bucket_pitch", "boom_angle", "edge_x", "edge_z"}};
}

template <>
std::vector<double> wheel_loader::WheelLoaderAdapter::scalars() const {
  const Reports r = model().reports();
  const V3 edge = model().cutting_edge();
  return {r.a_long,    r.a_vert,      r.j_long,      r.j_vert,       r.lift_force,
          r.tilt_force, r.speed,      r.x_machine,   r.drive_force,  r.normal_load,
          r.bucket_pitch, r.boom_angle, edge[0],     edge[2]};
}

template <>
std::vector<std::pair<std::string, double>> wheel_loader::WheelLoaderAdapter::diagnostics() const {
  const Reports r = model().reports();
  return {{"normal_front", r.normal_front}, {"normal_rear", r.normal_rear},
          {"lift_length", r.lift_length}, {"tilt_length", r.tilt_length}};
}

}  // namespace mbs
