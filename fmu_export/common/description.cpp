#include "description.hpp"

#include <charconv>
#include <cmath>
#include <set>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace fmu_export {
namespace {

std::string xml_escaped(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

// Shortest text that reads back as the same double ("10", "5e-06").
std::string number(double v) {
  char buf[40];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

const char* type_name(Type t) {
  switch (t) {
    case Type::Real: return "Real";
    case Type::Integer: return "Integer";
    case Type::String: return "String";
  }
  return "?";
}

const char* causality_name(Causality c) {
  switch (c) {
    case Causality::Parameter: return "parameter";
    case Causality::Input: return "input";
    case Causality::Output: return "output";
  }
  return "?";
}

// FNV-1a, 64 bits, twice with different bases: 128 bits shown as a GUID.
std::uint64_t fnv(const std::string& s, std::uint64_t h) {
  for (unsigned char c : s) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  return h;
}

// Every unit the variables use, declared as FMI 2.0 asks (UnitDefinitions).
std::string unit_definitions(const Description& d) {
  std::set<std::string> units;
  for (const auto& v : d.variables)
    if (v.type == Type::Real && !v.unit.empty()) units.insert(v.unit);
  if (units.empty()) return "";
  std::string x = "  <UnitDefinitions>\n";
  for (const auto& u : units) x += "    <Unit name=\"" + xml_escaped(u) + "\"/>\n";
  return x + "  </UnitDefinitions>\n";
}

}  // namespace

std::string Description::guid() const {
  std::ostringstream all;
  all << model_identifier << '|' << model_name << '|' << can_get_and_set_state << '|'
      << can_interpolate_inputs;
  for (const auto& v : variables)
    all << '|' << v.name << ',' << type_name(v.type) << ',' << v.vr << ','
        << causality_name(v.causality) << ',' << number(v.start) << ',' << v.start_string;
  const std::uint64_t a = fnv(all.str(), 0xcbf29ce484222325ULL), b = fnv(all.str(), 0x84222325cbf29ce4ULL);
  char buf[48];
  std::snprintf(buf, sizeof buf, "{%08x-%04x-%04x-%04x-%012llx}", static_cast<unsigned>(a >> 32),
                static_cast<unsigned>((a >> 16) & 0xffff), static_cast<unsigned>(a & 0xffff),
                static_cast<unsigned>(b >> 48), static_cast<unsigned long long>(b & 0xffffffffffffULL));
  return buf;
}

const Variable* Description::find(Type type, fmi2ValueReference vr) const {
  for (const auto& v : variables)
    if (v.type == type && v.vr == vr) return &v;
  return nullptr;
}

const Variable* Description::find(const std::string& name) const {
  for (const auto& v : variables)
    if (v.name == name) return &v;
  return nullptr;
}

std::string model_description_xml(const Description& d) {
  std::ostringstream x;
  x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
    << "<!-- Written by " << d.model_identifier << "_describe at build time (fmu_export/, docs/fmi.md). -->\n"
    << "<fmiModelDescription fmiVersion=\"2.0\" modelName=\"" << xml_escaped(d.model_name)
    << "\" guid=\"" << d.guid() << "\" description=\"" << xml_escaped(d.description)
    << "\" generationTool=\"soilcosim fmu_export\" variableNamingConvention=\"flat\""
    << " numberOfEventIndicators=\"0\">\n"
    << "  <CoSimulation modelIdentifier=\"" << d.model_identifier << "\""
    << " needsExecutionTool=\"false\" canHandleVariableCommunicationStepSize=\"true\""
    << " canInterpolateInputs=\"" << (d.can_interpolate_inputs ? "true" : "false") << "\""
    << " maxOutputDerivativeOrder=\"0\" canRunAsynchronuously=\"false\""
    << " canBeInstantiatedOnlyOncePerProcess=\"false\" canNotUseMemoryManagementFunctions=\"true\""
    << " canGetAndSetFMUstate=\"" << (d.can_get_and_set_state ? "true" : "false") << "\""
    << " canSerializeFMUstate=\"false\" providesDirectionalDerivative=\"false\"/>\n"
    << unit_definitions(d) << "  <LogCategories>\n"
    << "    <Category name=\"logStatusError\" description=\"errors: why a call returned fmi2Error\"/>\n"
    << "    <Category name=\"logStatusWarning\" description=\"warnings\"/>\n"
    << "    <Category name=\"logEvents\" description=\"what the FMU does: initialization, connections\"/>\n"
    << "  </LogCategories>\n"
    << "  <DefaultExperiment startTime=\"" << number(d.default_start) << "\" stopTime=\""
    << number(d.default_stop) << "\" stepSize=\"" << number(d.default_step) << "\"/>\n"
    << "  <ModelVariables>\n";
  for (std::size_t i = 0; i < d.variables.size(); ++i) {
    const Variable& v = d.variables[i];
    x << "    <!-- index " << i + 1 << " -->\n"
      << "    <ScalarVariable name=\"" << xml_escaped(v.name) << "\" valueReference=\"" << v.vr
      << "\" description=\"" << xml_escaped(v.description) << "\" causality=\""
      << causality_name(v.causality) << "\" variability=\""
      << (v.variability == Variability::Fixed ? "fixed" : "continuous") << "\"";
    if (v.causality == Causality::Output) x << " initial=\"calculated\"";
    x << ">\n      <" << type_name(v.type);
    if (v.type == Type::Real && !v.unit.empty()) x << " unit=\"" << xml_escaped(v.unit) << "\"";
    if (v.causality != Causality::Output) {
      if (v.type == Type::String) x << " start=\"" << xml_escaped(v.start_string) << "\"";
      else if (v.type == Type::Integer) x << " start=\"" << static_cast<long long>(v.start) << "\"";
      else x << " start=\"" << number(v.start) << "\"";
    }
    x << "/>\n    </ScalarVariable>\n";
  }
  x << "  </ModelVariables>\n  <ModelStructure>\n    <Outputs>\n";
  auto index_of = [&](const std::string& name) {
    for (std::size_t i = 0; i < d.variables.size(); ++i)
      if (d.variables[i].name == name) return i + 1;
    return std::size_t{0};
  };
  for (std::size_t i = 0; i < d.variables.size(); ++i) {
    const Variable& v = d.variables[i];
    if (v.causality != Causality::Output) continue;
    x << "      <Unknown index=\"" << i + 1 << "\" dependencies=\"";
    for (std::size_t k = 0; k < v.depends_on.size(); ++k) x << (k ? " " : "") << index_of(v.depends_on[k]);
    x << "\"/>\n";
  }
  x << "    </Outputs>\n    <InitialUnknowns>\n";
  for (std::size_t i = 0; i < d.variables.size(); ++i)
    if (d.variables[i].causality == Causality::Output) x << "      <Unknown index=\"" << i + 1 << "\"/>\n";
  x << "    </InitialUnknowns>\n  </ModelStructure>\n</fmiModelDescription>\n";
  return x.str();
}

}  // namespace fmu_export
