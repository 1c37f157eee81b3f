// The wheel-loader FMU's variable table, shared by its modelDescription.xml (description.cpp)
// and its slave (wheel_loader_fmu.cpp): value references and the scalar parameters, whose
// names are the dotted keys of the machine config (configs/wheel_loader/machine.yaml).
#pragma once

#include <cosim_fmi2.h>

#include <string>
#include <vector>

#include "parameters.hpp"

namespace fmu_export::wl {

// Inputs: the soil's wrench on the bucket, ground axes, torque about reference_point (ground):
// the native adapter's bucket_wrench port.
constexpr fmi2ValueReference kForce = 0, kTorque = 3, kPoint = 6;
// Outputs: the bucket frame (origin at the A-pin) as the native adapter's bucket port sends it.
constexpr fmi2ValueReference kPosition = 100, kQuaternion = 103, kVelocity = 107, kAngularVelocity = 110;
// Then the native adapter's scalar outputs, in kScalarOutputs order.
constexpr fmi2ValueReference kScalars = 120;
// String parameters.
constexpr fmi2ValueReference kMachineConfig = 300, kMachineParameters = 301;

struct ScalarOutput {
  const char* name;
  const char* unit;
  const char* description;
  bool feedthrough;  // depends directly on the wrench inputs (constraint reactions)
};
const std::vector<ScalarOutput>& scalar_outputs();

// A Real parameter: its name is the machine config's dotted key.
struct ScalarParameter {
  std::string key;
  fmi2ValueReference vr;
  double native_default;
  std::string unit, description;
};
const std::vector<ScalarParameter>& scalar_parameters();

}  // namespace fmu_export::wl
