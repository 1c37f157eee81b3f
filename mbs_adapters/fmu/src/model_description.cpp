#include "model_description.hpp"

#include <pugixml.hpp>

#include <cerrno>
#include <cstdlib>
#include <set>

namespace fmu {

const char* type_name(VarType t) {
  switch (t) {
    case VarType::Real: return "Real";
    case VarType::Integer: return "Integer";
    case VarType::Boolean: return "Boolean";
    case VarType::String: return "String";
    case VarType::Enumeration: return "Enumeration";
    case VarType::Float32: return "Float32";
    case VarType::Float64: return "Float64";
    case VarType::Int8: return "Int8";
    case VarType::UInt8: return "UInt8";
    case VarType::Int16: return "Int16";
    case VarType::UInt16: return "UInt16";
    case VarType::Int32: return "Int32";
    case VarType::UInt32: return "UInt32";
    case VarType::Int64: return "Int64";
    case VarType::UInt64: return "UInt64";
    case VarType::Binary: return "Binary";
    case VarType::Clock: return "Clock";
  }
  return "?";
}

bool is_float(VarType t) { return t == VarType::Real || t == VarType::Float32 || t == VarType::Float64; }

bool is_integer(VarType t) {
  switch (t) {
    case VarType::Integer: case VarType::Enumeration: case VarType::Int8: case VarType::UInt8: case VarType::Int16:
    case VarType::UInt16: case VarType::Int32: case VarType::UInt32: case VarType::Int64: case VarType::UInt64:
      return true;
    default:
      return false;
  }
}

void integer_range(VarType t, long double* lo, long double* hi) {
  switch (t) {
    case VarType::Int8: *lo = -128.0L; *hi = 127.0L; return;
    case VarType::UInt8: *lo = 0; *hi = 255.0L; return;
    case VarType::Int16: *lo = -32768.0L; *hi = 32767.0L; return;
    case VarType::UInt16: *lo = 0; *hi = 65535.0L; return;
    case VarType::UInt32: *lo = 0; *hi = 4294967295.0L; return;
    case VarType::Int64: *lo = -9223372036854775808.0L; *hi = 9223372036854775807.0L; return;
    case VarType::UInt64: *lo = 0; *hi = 18446744073709551615.0L; return;
    default: *lo = -2147483648.0L; *hi = 2147483647.0L; return;  // Integer, Int32, FMI 2.0 Enumeration
  }
}

const char* causality_name(Causality c) {
  switch (c) {
    case Causality::Parameter: return "parameter";
    case Causality::CalculatedParameter: return "calculatedParameter";
    case Causality::Input: return "input";
    case Causality::Output: return "output";
    case Causality::Local: return "local";
    case Causality::Independent: return "independent";
    case Causality::StructuralParameter: return "structuralParameter";
  }
  return "?";
}

const char* variability_name(Variability v) {
  switch (v) {
    case Variability::Constant: return "constant";
    case Variability::Fixed: return "fixed";
    case Variability::Tunable: return "tunable";
    case Variability::Discrete: return "discrete";
    case Variability::Continuous: return "continuous";
  }
  return "?";
}

const char* initial_name(Initial i) {
  switch (i) {
    case Initial::None: return "(none)";
    case Initial::Exact: return "exact";
    case Initial::Approx: return "approx";
    case Initial::Calculated: return "calculated";
  }
  return "?";
}

const Variable* ModelDescription::find(const std::string& name) const {
  for (const auto& v : variables)
    if (v.name == name) return &v;
  return nullptr;
}

const Variable* ModelDescription::find_by_reference(unsigned value_reference) const {
  for (const auto& v : variables)
    if (v.value_reference == value_reference) return &v;
  return nullptr;
}

namespace {

bool bool_attribute(const pugi::xml_node& n, const char* name, const std::string& what) {
  const pugi::xml_attribute a = n.attribute(name);
  if (!a) return false;
  const std::string v = a.value();
  if (v == "true" || v == "1") return true;
  if (v == "false" || v == "0") return false;
  throw FmuError(what + ": attribute " + name + "=\"" + v + "\" is not a boolean (true or false)");
}

std::optional<double> double_attribute(const pugi::xml_node& n, const char* name, const std::string& what) {
  const pugi::xml_attribute a = n.attribute(name);
  if (!a) return std::nullopt;
  const char* text = a.value();
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || errno == ERANGE)
    throw FmuError(what + ": attribute " + name + "=\"" + text + "\" is not a number");
  return v;
}

// The <CoSimulation> element (an FMU without it is refused, naming what it offers instead) and
// its modelIdentifier into `md`.
pugi::xml_node cosimulation_element(const pugi::xml_node& root, ModelDescription& md, const std::string& what) {
  const pugi::xml_node cs = root.child("CoSimulation");
  if (!cs)
    throw FmuError(what + ": no <CoSimulation> element: the FMU offers " +
                   (md.has_model_exchange ? std::string("Model Exchange only")
                    : root.child("ScheduledExecution") ? std::string("Scheduled Execution only")
                                                       : std::string("no interface")) +
                   "; fmu_adapter needs a co-simulation FMU (export it with the co-simulation interface, solver included)");
  md.model_identifier = cs.attribute("modelIdentifier").value();
  if (md.model_identifier.empty()) throw FmuError(what + ": <CoSimulation> has no modelIdentifier");
  return cs;
}

// <DefaultExperiment>, where there is one, into `md`.
void read_default_experiment(const pugi::xml_node& root, ModelDescription& md, const std::string& what) {
  if (const pugi::xml_node de = root.child("DefaultExperiment")) {
    const std::string de_what = what + " <DefaultExperiment>";
    md.default_experiment.start_time = double_attribute(de, "startTime", de_what);
    md.default_experiment.stop_time = double_attribute(de, "stopTime", de_what);
    md.default_experiment.tolerance = double_attribute(de, "tolerance", de_what);
    md.default_experiment.step_size = double_attribute(de, "stepSize", de_what);
  }
}

}  // namespace

namespace {

Causality parse_causality(const std::string& causality, const std::string& vwhat, const std::string& name) {
  if (causality.empty() || causality == "local") return Causality::Local;
  if (causality == "parameter") return Causality::Parameter;
  if (causality == "calculatedParameter") return Causality::CalculatedParameter;
  if (causality == "input") return Causality::Input;
  if (causality == "output") return Causality::Output;
  if (causality == "independent") return Causality::Independent;
  if (causality == "structuralParameter") return Causality::StructuralParameter;
  throw FmuError(vwhat + " ('" + name + "'): unknown causality \"" + causality + "\"");
}

Variability parse_variability(const std::string& variability, const std::string& vwhat, const std::string& name,
                              VarType type) {
  if (variability.empty())  // FMI 3.0: continuous for floats, else discrete
    return is_float(type) ? Variability::Continuous : Variability::Discrete;
  if (variability == "continuous") return Variability::Continuous;
  if (variability == "constant") return Variability::Constant;
  if (variability == "fixed") return Variability::Fixed;
  if (variability == "tunable") return Variability::Tunable;
  if (variability == "discrete") return Variability::Discrete;
  throw FmuError(vwhat + " ('" + name + "'): unknown variability \"" + variability + "\"");
}

Initial parse_initial(const std::string& initial, const std::string& vwhat, const std::string& name) {
  if (initial.empty()) return Initial::None;
  if (initial == "exact") return Initial::Exact;
  if (initial == "approx") return Initial::Approx;
  if (initial == "calculated") return Initial::Calculated;
  throw FmuError(vwhat + " ('" + name + "'): unknown initial \"" + initial + "\"");
}

unsigned parse_reference(const char* text, const std::string& vwhat, const std::string& name) {
  char* end = nullptr;
  errno = 0;
  const unsigned long n = std::strtoul(text, &end, 10);
  if (end == text || *end != '\0' || errno == ERANGE || n > 0xffffffffUL || text[0] == '-')
    throw FmuError(vwhat + " ('" + name + "'): valueReference \"" + text + "\" is not an unsigned integer");
  return static_cast<unsigned>(n);
}

// FMI 3.0 (section 2.4): typed variable elements (<Float64 .../>, ...) under <ModelVariables>,
// <Dimension> children for arrays, <Start value=.../> children for String and Binary.
ModelDescription parse_fmi3(const pugi::xml_node& root, ModelDescription md, const std::string& what) {
  md.fmi_major = 3;
  md.model_name = root.attribute("modelName").value();
  md.guid = root.attribute("instantiationToken").value();
  md.generation_tool = root.attribute("generationTool").value();
  if (md.guid.empty()) throw FmuError(what + ": no instantiationToken attribute (required by FMI 3.0)");
  md.has_model_exchange = static_cast<bool>(root.child("ModelExchange"));
  const pugi::xml_node cs = cosimulation_element(root, md, what);
  const std::string cs_what = what + " <CoSimulation>";
  md.can_get_and_set_fmu_state = bool_attribute(cs, "canGetAndSetFMUState", cs_what);
  md.can_serialize_fmu_state = bool_attribute(cs, "canSerializeFMUState", cs_what);
  md.can_handle_variable_step = bool_attribute(cs, "canHandleVariableCommunicationStepSize", cs_what);
  md.needs_execution_tool = bool_attribute(cs, "needsExecutionTool", cs_what);
  md.provides_intermediate_update = bool_attribute(cs, "providesIntermediateUpdate", cs_what);
  md.can_return_early = bool_attribute(cs, "canReturnEarlyAfterIntermediateUpdate", cs_what);
  md.might_return_early = bool_attribute(cs, "mightReturnEarlyFromDoStep", cs_what);
  md.has_event_mode = bool_attribute(cs, "hasEventMode", cs_what);
  md.fixed_internal_step_size = double_attribute(cs, "fixedInternalStepSize", cs_what);
  read_default_experiment(root, md, what);
  std::map<std::string, std::string> units;  // declared type -> unit
  if (const pugi::xml_node types = root.child("TypeDefinitions"))
    for (const pugi::xml_node t : types.children()) {
      const std::string tn = t.name();
      if (tn == "EnumerationType") {
        auto& items = md.enumerations[t.attribute("name").value()];
        for (const pugi::xml_node item : t.children("Item")) items[item.attribute("name").value()] = item.attribute("value").as_int();
      } else if (t.attribute("unit")) {
        units[t.attribute("name").value()] = t.attribute("unit").value();
      }
    }
  const pugi::xml_node vars = root.child("ModelVariables");
  if (!vars) throw FmuError(what + ": no <ModelVariables> element");
  static const std::map<std::string, VarType> kTypes{
      {"Float32", VarType::Float32}, {"Float64", VarType::Float64}, {"Int8", VarType::Int8},
      {"UInt8", VarType::UInt8},     {"Int16", VarType::Int16},     {"UInt16", VarType::UInt16},
      {"Int32", VarType::Int32},     {"UInt32", VarType::UInt32},   {"Int64", VarType::Int64},
      {"UInt64", VarType::UInt64},   {"Boolean", VarType::Boolean}, {"String", VarType::String},
      {"Binary", VarType::Binary},   {"Enumeration", VarType::Enumeration}, {"Clock", VarType::Clock}};
  std::set<std::string> names;
  std::set<unsigned> references;
  int index = 0;
  for (const pugi::xml_node sv : vars.children()) {
    if (sv.type() != pugi::node_element) continue;
    ++index;
    const std::string tn = sv.name();
    const std::string vwhat = what + ": variable " + std::to_string(index) + " <" + tn + ">";
    const auto type = kTypes.find(tn);
    if (type == kTypes.end()) throw FmuError(vwhat + " is not an FMI 3.0 variable type");
    Variable v;
    v.type = type->second;
    v.name = sv.attribute("name").value();
    if (v.name.empty()) throw FmuError(vwhat + " has no name");
    const pugi::xml_attribute vr = sv.attribute("valueReference");
    if (!vr) throw FmuError(vwhat + " ('" + v.name + "') has no valueReference");
    v.value_reference = parse_reference(vr.value(), vwhat, v.name);
    if (!names.insert(v.name).second) throw FmuError(vwhat + ": the name '" + v.name + "' is used twice");
    if (!references.insert(v.value_reference).second)
      throw FmuError(vwhat + " ('" + v.name + "'): valueReference " + std::to_string(v.value_reference) +
                     " is used twice (FMI 3.0 value references are unique)");
    v.description = sv.attribute("description").value();
    v.causality = parse_causality(sv.attribute("causality").value(), vwhat, v.name);
    v.variability = parse_variability(sv.attribute("variability").value(), vwhat, v.name, v.type);
    v.initial = parse_initial(sv.attribute("initial").value(), vwhat, v.name);
    if (const pugi::xml_attribute st = sv.attribute("start")) v.start = st.value();
    if (v.type == VarType::String || v.type == VarType::Binary)
      if (const pugi::xml_node st = sv.child("Start")) v.start = st.attribute("value").value();
    v.declared_type = sv.attribute("declaredType").value();
    v.unit = sv.attribute("unit").value();
    if (v.unit.empty() && units.count(v.declared_type)) v.unit = units[v.declared_type];
    for (const pugi::xml_node d : sv.children("Dimension")) {
      Variable::Dimension dim;
      if (const pugi::xml_attribute a = d.attribute("start")) dim.start = a.as_ullong();
      if (const pugi::xml_attribute a = d.attribute("valueReference")) dim.value_reference = parse_reference(a.value(), vwhat, v.name);
      if (dim.start.has_value() == dim.value_reference.has_value())
        throw FmuError(vwhat + " ('" + v.name + "'): a <Dimension> needs exactly one of start and valueReference");
      v.dimensions.push_back(dim);
    }
    if (v.initial == Initial::None) {
      if (v.causality == Causality::Parameter || v.causality == Causality::StructuralParameter ||
          v.variability == Variability::Constant || v.causality == Causality::Input)
        v.initial = Initial::Exact;
      else if (v.causality == Causality::CalculatedParameter)
        v.initial = Initial::Calculated;
      else if (v.causality == Causality::Output || v.causality == Causality::Local)
        v.initial = v.start ? Initial::Exact : Initial::Calculated;
    }
    md.variables.push_back(std::move(v));
  }
  for (const auto& v : md.variables)
    for (const auto& d : v.dimensions)
      if (d.value_reference) {
        const Variable* s = md.find_by_reference(*d.value_reference);
        if (!s || !is_integer(s->type) || s->type == VarType::Enumeration)
          throw FmuError(what + ": variable '" + v.name + "' has a <Dimension valueReference=\"" +
                         std::to_string(*d.value_reference) + "\"> that names no integer variable");
      }
  return md;
}

}  // namespace

ModelDescription parse_model_description(const std::string& xml, const std::string& fmu) {
  const std::string what = "FMU '" + fmu + "': modelDescription.xml";
  pugi::xml_document doc;
  const pugi::xml_parse_result ok = doc.load_buffer(xml.data(), xml.size());
  if (!ok) {
    // The line of the offset, for people.
    const std::size_t at = static_cast<std::size_t>(ok.offset);
    std::size_t line = 1;
    for (std::size_t i = 0; i < at && i < xml.size(); ++i) line += xml[i] == '\n';
    throw FmuError(what + " is malformed XML: " + ok.description() + " at line " +
                   std::to_string(line) + " (byte " + std::to_string(at) +
                   "); the FMU is damaged: export it again from its tool");
  }
  const pugi::xml_node root = doc.child("fmiModelDescription");
  if (!root)
    throw FmuError(what + ": the root element is not <fmiModelDescription>; this is not an FMU's model description");
  ModelDescription md;
  md.fmi_version = root.attribute("fmiVersion").value();
  if (md.fmi_version.empty())
    throw FmuError(what + ": no fmiVersion attribute");
  if (md.fmi_version.rfind("3.", 0) == 0) return parse_fmi3(root, std::move(md), what);
  if (md.fmi_version != "2.0")
    throw FmuError(what + ": fmiVersion is \"" + md.fmi_version +
                   "\"; fmu_adapter imports FMI 2.0 and 3.0 (export the model as an FMI 2.0 or 3.0 co-simulation FMU)");
  md.model_name = root.attribute("modelName").value();
  md.guid = root.attribute("guid").value();
  md.generation_tool = root.attribute("generationTool").value();
  if (md.guid.empty()) throw FmuError(what + ": no guid attribute (required by FMI 2.0)");
  md.has_model_exchange = static_cast<bool>(root.child("ModelExchange"));
  const pugi::xml_node cs = cosimulation_element(root, md, what);
  const std::string cs_what = what + " <CoSimulation>";
  md.can_get_and_set_fmu_state = bool_attribute(cs, "canGetAndSetFMUstate", cs_what);
  md.can_serialize_fmu_state = bool_attribute(cs, "canSerializeFMUstate", cs_what);
  md.can_handle_variable_step = bool_attribute(cs, "canHandleVariableCommunicationStepSize", cs_what);
  md.can_interpolate_inputs = bool_attribute(cs, "canInterpolateInputs", cs_what);
  md.needs_execution_tool = bool_attribute(cs, "needsExecutionTool", cs_what);

  read_default_experiment(root, md, what);

  if (const pugi::xml_node types = root.child("TypeDefinitions")) {
    for (const pugi::xml_node st : types.children("SimpleType")) {
      const pugi::xml_node e = st.child("Enumeration");
      if (!e) continue;
      auto& items = md.enumerations[st.attribute("name").value()];
      for (const pugi::xml_node item : e.children("Item"))
        items[item.attribute("name").value()] = item.attribute("value").as_int();
    }
  }

  const pugi::xml_node vars = root.child("ModelVariables");
  if (!vars) throw FmuError(what + ": no <ModelVariables> element");
  std::set<std::string> names;
  int index = 0;
  for (const pugi::xml_node sv : vars.children("ScalarVariable")) {
    ++index;
    const std::string vwhat = what + ": ScalarVariable " + std::to_string(index);
    Variable v;
    v.name = sv.attribute("name").value();
    if (v.name.empty()) throw FmuError(vwhat + " has no name");
    const pugi::xml_attribute vr = sv.attribute("valueReference");
    if (!vr) throw FmuError(vwhat + " ('" + v.name + "') has no valueReference");
    {
      const char* text = vr.value();
      char* end = nullptr;
      errno = 0;
      const unsigned long n = std::strtoul(text, &end, 10);
      if (end == text || *end != '\0' || errno == ERANGE || n > 0xffffffffUL || text[0] == '-')
        throw FmuError(vwhat + " ('" + v.name + "'): valueReference \"" + text + "\" is not an unsigned integer");
      v.value_reference = static_cast<unsigned>(n);
    }
    if (!names.insert(v.name).second) throw FmuError(vwhat + ": the name '" + v.name + "' is used twice");
    v.description = sv.attribute("description").value();
    const std::string causality = sv.attribute("causality").value();
    if (causality.empty() || causality == "local") v.causality = Causality::Local;
    else if (causality == "parameter") v.causality = Causality::Parameter;
    else if (causality == "calculatedParameter") v.causality = Causality::CalculatedParameter;
    else if (causality == "input") v.causality = Causality::Input;
    else if (causality == "output") v.causality = Causality::Output;
    else if (causality == "independent") v.causality = Causality::Independent;
    else throw FmuError(vwhat + " ('" + v.name + "'): unknown causality \"" + causality + "\"");
    const std::string variability = sv.attribute("variability").value();
    if (variability.empty() || variability == "continuous") v.variability = Variability::Continuous;
    else if (variability == "constant") v.variability = Variability::Constant;
    else if (variability == "fixed") v.variability = Variability::Fixed;
    else if (variability == "tunable") v.variability = Variability::Tunable;
    else if (variability == "discrete") v.variability = Variability::Discrete;
    else throw FmuError(vwhat + " ('" + v.name + "'): unknown variability \"" + variability + "\"");
    const std::string initial = sv.attribute("initial").value();
    if (initial.empty()) v.initial = Initial::None;
    else if (initial == "exact") v.initial = Initial::Exact;
    else if (initial == "approx") v.initial = Initial::Approx;
    else if (initial == "calculated") v.initial = Initial::Calculated;
    else throw FmuError(vwhat + " ('" + v.name + "'): unknown initial \"" + initial + "\"");
    pugi::xml_node type;
    for (const char* t : {"Real", "Integer", "Boolean", "String", "Enumeration"})
      if (const pugi::xml_node n = sv.child(t)) {
        type = n;
        break;
      }
    if (!type) throw FmuError(vwhat + " ('" + v.name + "') has no type element (Real, Integer, Boolean, String or Enumeration)");
    const std::string tn = type.name();
    v.type = tn == "Real" ? VarType::Real
             : tn == "Integer" ? VarType::Integer
             : tn == "Boolean" ? VarType::Boolean
             : tn == "String" ? VarType::String
                              : VarType::Enumeration;
    if (const pugi::xml_attribute s = type.attribute("start")) v.start = s.value();
    v.declared_type = type.attribute("declaredType").value();
    v.unit = type.attribute("unit").value();
    // FMI 2.0 table of defaults: initial follows from causality and variability.
    if (v.initial == Initial::None) {
      if (v.causality == Causality::Parameter || v.variability == Variability::Constant ||
          v.causality == Causality::Input)
        v.initial = Initial::Exact;
      else if (v.causality == Causality::CalculatedParameter || v.causality == Causality::Output ||
               v.causality == Causality::Local)
        v.initial = v.start ? Initial::Exact : Initial::Calculated;
    }
    md.variables.push_back(std::move(v));
  }
  return md;
}

}  // namespace fmu
