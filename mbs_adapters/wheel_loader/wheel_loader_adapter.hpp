// The wheel loader on the bus (mbs_adapters/common/machine_adapter.hpp), machine config
// configs/wheel_loader/machine.yaml:
//   input   bucket_wrench  (wrench: force, torque about r, r; ground)
//   outputs bucket         (kinematics of the bucket frame: origin = A-pin)
//           a_long a_vert j_long j_vert   section forces on the bucket, bucket frame [N]
//           lift_force tilt_force         cylinder forces, positive pushing [N]
//           speed x_machine drive_force normal_load bucket_pitch boom_angle edge_x edge_z
//   diagnostics normal_front normal_rear lift_length tilt_length
#pragma once

#include "machine_adapter.hpp"
#include "wheel_loader.hpp"

namespace wheel_loader {
using WheelLoaderAdapter = mbs::MachineAdapterOf<WheelLoader, Parameters>;
}  // namespace wheel_loader

namespace mbs {
template <>
MachineAdapter::Settings wheel_loader::WheelLoaderAdapter::read(const YAML::Node& config);
template <>
std::vector<double> wheel_loader::WheelLoaderAdapter::scalars() const;
template <>
std::vector<std::pair<std::string, double>> wheel_loader::WheelLoaderAdapter::diagnostics() const;
}  // namespace mbs
