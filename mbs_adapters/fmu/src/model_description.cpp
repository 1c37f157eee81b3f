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
  }
  return "?";
}

const char* causality_name(Causality c) {
  switch (c) {
    case Causality::Parameter: return "parameter";
    case Causality::CalculatedParameter: return "calculatedParameter";
    case Causality::Input: return "input";
    case Causality::Output: return "output";
    case Causality::Local: return "local";
    case Causality::Independent: return "independent";
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
  if (md.fmi_version != "2.0")
    throw FmuError(what + ": fmiVersion is \"" + md.fmi_version +
                   "\"; fmu_adapter imports FMI 2.0 only (export the model as an FMI 2.0 co-simulation FMU)");
  md.model_name = root.attribute("modelName").value();
  md.guid = root.attribute("guid").value();
  md.generation_tool = root.attribute("generationTool").value();
  if (md.guid.empty()) throw FmuError(what + ": no guid attribute (required by FMI 2.0)");
  md.has_model_exchange = static_cast<bool>(root.child("ModelExchange"));
  const pugi::xml_node cs = root.child("CoSimulation");
  if (!cs)
    throw FmuError(what + ": no <CoSimulation> element: the FMU offers " +
                   (md.has_model_exchange ? std::string("Model Exchange only") : std::string("no interface")) +
                   "; fmu_adapter needs a co-simulation FMU (export it with the co-simulation interface, solver included)");
  md.model_identifier = cs.attribute("modelIdentifier").value();
  if (md.model_identifier.empty()) throw FmuError(what + ": <CoSimulation> has no modelIdentifier");
  const std::string cs_what = what + " <CoSimulation>";
  md.can_get_and_set_fmu_state = bool_attribute(cs, "canGetAndSetFMUstate", cs_what);
  md.can_handle_variable_step = bool_attribute(cs, "canHandleVariableCommunicationStepSize", cs_what);
  md.can_interpolate_inputs = bool_attribute(cs, "canInterpolateInputs", cs_what);
  md.needs_execution_tool = bool_attribute(cs, "needsExecutionTool", cs_what);

  if (const pugi::xml_node de = root.child("DefaultExperiment")) {
    const std::string de_what = what + " <DefaultExperiment>";
    md.default_experiment.start_time = double_attribute(de, "startTime", de_what);
    md.default_experiment.stop_time = double_attribute(de, "stopTime", de_what);
    md.default_experiment.tolerance = double_attribute(de, "tolerance", de_what);
    md.default_experiment.step_size = double_attribute(de, "stepSize", de_what);
  }

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
