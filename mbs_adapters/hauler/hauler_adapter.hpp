// The hauler on the bus (mbs_adapters/common/machine_adapter.hpp), machine config
// configs/hauler/machine.yaml:
//   input   body_wrench    (wrench: force, torque about r, r; ground) on the dump body
//   outputs body           (kinematics of the body frame: origin on the hinge axis at the
//                           centre plane, x forward along the floor, z up from the floor)
//           front_fx front_fz rear1_fx rear1_fz rear2_fx rear2_fz
//                          tire forces on the machine per axle, TYDEX C axes [N]
//           front_stroke rear1_stroke rear2_stroke    strut strokes [m]
//           front_pressure rear_pressure              circuit pressures [Pa]
//           hoist_force [N]  body_angle [rad]
//           payload_rigid [kg]   only with a rigid test payload
//   diagnostics kinetic_energy front_oil rear_oil front_level_flow rear_level_flow
//           front_ride_filtered rear_ride_filtered hoist_length pitch
#pragma once

#include "hauler.hpp"
#include "machine_adapter.hpp"

namespace hauler {
using HaulerAdapter = mbs::MachineAdapterOf<Hauler, Parameters>;
}  // namespace hauler

namespace mbs {
template <>
MachineAdapter::Settings hauler::HaulerAdapter::read(const YAML::Node& config);
template <>
std::vector<double> hauler::HaulerAdapter::scalars() const;
template <>
std::vector<std::pair<std::string, double>> hauler::HaulerAdapter::diagnostics() const;
}  // namespace mbs
