#include "hauler_adapter.hpp"

using hauler::kFront;
using hauler::kRear1;
using hauler::kRear2;

namespace mbs {

template <>
MachineAdapter::Settings hauler::HaulerAdapter::read(const YAML::Node& config) {
  p_ = hauler::read_parameters(config);
  Settings s{"body", p_.inner_step, p_.max_force, p_.max_torque,
             {"front_fx", "front_fz", "rear1_fx", "rear1_fz", "rear2_fx", "rear2_fz", "front_stroke",
              "rear1_stroke", "rear2_stroke", "front_pressure", "rear_pressure", "hoist_force",
              "body_angle"}};
  if (p_.test_payload) s.scalars.push_back("payload_rigid");
  return s;
}

template <>
std::vector<double> hauler::HaulerAdapter::scalars() const {
  const hauler::Reports r = model().reports();
  std::vector<double> v{r.axle[kFront].fx,     r.axle[kFront].fz,     r.axle[kRear1].fx,
                        r.axle[kRear1].fz,     r.axle[kRear2].fx,     r.axle[kRear2].fz,
                        r.axle[kFront].stroke, r.axle[kRear1].stroke, r.axle[kRear2].stroke,
                        r.front.pressure,      r.rear.pressure,       r.hoist_force,
                        r.body_angle};
  if (p_.test_payload) v.push_back(p_.test_payload->mass);
  return v;
}

template <>
std::vector<std::pair<std::string, double>> hauler::HaulerAdapter::diagnostics() const {
  const hauler::Reports r = model().reports();
  return {{"kinetic_energy", r.kinetic_energy},
          {"front_oil", r.front.oil},
          {"rear_oil", r.rear.oil},
          {"front_level_flow", r.front.flow},
          {"rear_level_flow", r.rear.flow},
          {"front_ride_filtered", r.front.ride_filtered},
          {"rear_ride_filtered", r.rear.ride_filtered},
          {"hoist_length", r.hoist_length},
          {"pitch", r.pitch}};
}

}  // namespace mbs
