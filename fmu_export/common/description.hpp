// What an FMU of this project declares: its variables and capabilities. One table per FMU is
// the single source of both its modelDescription.xml (written at build time by the FMU's
// `<id>_describe` program) and the checks its fmi2 functions make at run time, so the two
// cannot drift apart.
#pragma once

#include <cosim_fmi2.h>

#include <string>
#include <vector>

namespace fmu_export {

enum class Type { Real, Integer, String };
enum class Causality { Parameter, Input, Output };
enum class Variability { Fixed, Continuous };

struct Variable {
  std::string name;
  Type type = Type::Real;
  fmi2ValueReference vr = 0;
  Causality causality = Causality::Parameter;
  Variability variability = Variability::Fixed;
  double start = 0;          // Real and Integer (Integer: a whole number)
  std::string start_string;  // String
  std::string unit;          // Real only; "" for none
  std::string description;
  // Outputs: the inputs (by name) the output depends on directly (feedthrough).
  std::vector<std::string> depends_on;
};

struct Description {
  std::string model_identifier;  // the .so's name and the CoSimulation modelIdentifier
  std::string model_name;
  std::string description;
  bool can_get_and_set_state = false;
  bool can_interpolate_inputs = false;  // fmi2SetRealInputDerivatives, orders 1..3
  double default_start = 0, default_stop = 1, default_step = 1e-3;
  std::vector<Variable> variables;

  // A GUID derived from everything above: an FMU whose interface changes gets a new one.
  std::string guid() const;
  // Null when absent.
  const Variable* find(Type type, fmi2ValueReference vr) const;
  const Variable* find(const std::string& name) const;
};

constexpr int kMaxInputDerivativeOrder = 3;

std::string model_description_xml(const Description& d);

// Defined by each FMU.
const Description& description();

}  // namespace fmu_export
