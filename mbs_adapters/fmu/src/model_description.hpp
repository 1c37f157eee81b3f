// modelDescription.xml of an FMI 2.0 or 3.0 co-simulation FMU: what the importer needs of it (FMI
// 2.0.x section 2.2; FMI 3.0 section 2.4). Parsed with pugixml; every problem raises FmuError
// naming the FMU. FMI 3.0's types map onto VarType; its arrays carry their dimensions.
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

// Real and Integer are FMI 2.0's; Float32 ... Clock are FMI 3.0's (its Enumeration is an Int64).
enum class VarType { Real, Integer, Boolean, String, Enumeration, Float32, Float64, Int8, UInt8, Int16, UInt16,
                     Int32, UInt32, Int64, UInt64, Binary, Clock };
enum class Causality { Parameter, CalculatedParameter, Input, Output, Local, Independent, StructuralParameter };

bool is_float(VarType t);    // Real, Float32, Float64
bool is_integer(VarType t);  // Integer, Enumeration, Int8 ... UInt64
// A number on the bus: floats, integers, Boolean (not String, Binary, Clock).
inline bool is_numeric(VarType t) { return is_float(t) || is_integer(t) || t == VarType::Boolean; }
// The range of an integer type, as long double (exact for every 64-bit bound).
void integer_range(VarType t, long double* lo, long double* hi);
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
  // FMI 3.0 arrays: one entry per <Dimension>, a fixed size (start) or the value reference of
  // the structural parameter that holds it. Empty: a scalar.
  struct Dimension {
    std::optional<unsigned long long> start;
    std::optional<unsigned> value_reference;
  };
  std::vector<Dimension> dimensions;
};

struct DefaultExperiment {
  std::optional<double> start_time, stop_time, tolerance, step_size;
};

struct ModelDescription {
  std::string fmi_version;
  int fmi_major = 2;  // 2 or 3
  std::string model_name;
  std::string guid;
  std::string generation_tool;
  // CoSimulation element
  std::string model_identifier;
  bool can_get_and_set_fmu_state = false;
  bool can_serialize_fmu_state = false;
  bool can_handle_variable_step = false;
  bool can_interpolate_inputs = false;
  bool needs_execution_tool = false;
  // FMI 3.0 <CoSimulation>
  bool provides_intermediate_update = false;
  bool can_return_early = false;  // canReturnEarlyAfterIntermediateUpdate
  bool might_return_early = false;  // mightReturnEarlyFromDoStep
  bool has_event_mode = false;
  std::optional<double> fixed_internal_step_size;
  bool has_model_exchange = false;
  DefaultExperiment default_experiment;
  std::vector<Variable> variables;
  // Enumeration items per declared type: item name -> value.
  std::map<std::string, std::map<std::string, int>> enumerations;

  // nullptr when there is none.
  const Variable* find(const std::string& name) const;
  const Variable* find_by_reference(unsigned value_reference) const;  // FMI 3.0: unique
};

// Parses the text of a modelDescription.xml; `fmu` names the FMU in messages. Refuses
// malformed XML, an fmiVersion other than 2.0 or 3.0, a description without a CoSimulation element,
// variables without name/valueReference/type and duplicate names.
ModelDescription parse_model_description(const std::string& xml, const std::string& fmu);

}  // namespace fmu
