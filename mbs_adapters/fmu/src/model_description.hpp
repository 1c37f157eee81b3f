// modelDescription.xml of an FMI 2.0 co-simulation FMU: what the importer needs of it (FMI 2.0.x
// standard, section 2.2). Parsed with pugixml; every problem raises FmuError naming the FMU.
#pragma once

#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace fmu {

// Any problem with an FMU (file, archive, XML, binary, a call that failed). The text names the
// FMU and the cause.
struct FmuError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

enum class VarType { Real, Integer, Boolean, String, Enumeration };
enum class Causality { Parameter, CalculatedParameter, Input, Output, Local, Independent };
enum class Variability { Constant, Fixed, Tunable, Discrete, Continuous };
enum class Initial { None, Exact, Approx, Calculated };

const char* type_name(VarType t);
const char* causality_name(Causality c);
const char* variability_name(Variability v);
const char* initial_name(Initial i);

struct Variable {
  std::string name;
  unsigned value_reference = 0;
  VarType type = VarType::Real;
  Causality causality = Causality::Local;
  Variability variability = Variability::Continuous;
  Initial initial = Initial::None;
  std::optional<std::string> start;  // the start attribute as written
  std::string declared_type;
  std::string description;
  std::string unit;
};

struct DefaultExperiment {
  std::optional<double> start_time, stop_time, tolerance, step_size;
};

struct ModelDescription {
  std::string fmi_version;
  std::string model_name;
  std::string guid;
  std::string generation_tool;
  // CoSimulation element
  std::string model_identifier;
  bool can_get_and_set_fmu_state = false;
  bool can_handle_variable_step = false;
  bool can_interpolate_inputs = false;
  bool needs_execution_tool = false;
  bool has_model_exchange = false;
  DefaultExperiment default_experiment;
  std::vector<Variable> variables;
  // Enumeration items per declared type: item name -> value.
  std::map<std::string, std::map<std::string, int>> enumerations;

  // nullptr when there is none.
  const Variable* find(const std::string& name) const;
};

// Parses the text of a modelDescription.xml; `fmu` names the FMU in messages. Refuses
// malformed XML, an fmiVersion other than 2.0, a description without a CoSimulation element,
// variables without name/valueReference/type and duplicate names.
ModelDescription parse_model_description(const std::string& xml, const std::string& fmu);

}  // namespace fmu
