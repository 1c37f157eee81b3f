#include "ssp_import.hpp"

#include <pugixml.hpp>
#include <sys/stat.h>
#include <unzip.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <vector>

#include <cosim/yaml_config.hpp>

namespace ssp {

namespace fs = std::filesystem;

namespace {

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// An XML file with line numbers for its nodes.
struct Xml {
  std::string path, text;
  pugi::xml_document doc;
  std::string at(const pugi::xml_node& n) const {
    std::size_t line = 1;
    const auto off = static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, n.offset_debug()));
    for (std::size_t i = 0; i < off && i < text.size(); ++i) line += text[i] == '\n';
    return path + ":" + std::to_string(line);
  }
  [[noreturn]] void fail(const pugi::xml_node& n, const std::string& why) const { throw SspError(at(n) + ": " + why); }
};

void load_xml(Xml& x, const std::string& path, const std::string& referenced_at) {
  x.path = path;
  if (!fs::is_regular_file(path))
    throw SspError((referenced_at.empty() ? path : referenced_at) + ": file not found: " + path);
  x.text = slurp(path);
  const pugi::xml_parse_result ok = x.doc.load_buffer(x.text.data(), x.text.size());
  if (!ok) {
    std::size_t line = 1;
    for (std::ptrdiff_t i = 0; i < ok.offset && static_cast<std::size_t>(i) < x.text.size(); ++i) line += x.text[i] == '\n';
    throw SspError(path + ":" + std::to_string(line) + ": malformed XML: " + ok.description());
  }
}

// Element name without its namespace prefix (ssd:, ssc:, ssv:, ...).
std::string local(const pugi::xml_node& n) {
  const std::string name = n.name();
  const auto colon = name.find(':');
  return colon == std::string::npos ? name : name.substr(colon + 1);
}

pugi::xml_node child(const pugi::xml_node& n, const std::string& name) {
  for (const pugi::xml_node c : n.children())
    if (c.type() == pugi::node_element && local(c) == name) return c;
  return {};
}

std::vector<pugi::xml_node> children(const pugi::xml_node& n, const std::string& name) {
  std::vector<pugi::xml_node> out;
  for (const pugi::xml_node c : n.children())
    if (c.type() == pugi::node_element && local(c) == name) out.push_back(c);
  return out;
}

bool valid_name(const std::string& s) {
  if (s.empty() || s.size() > 32) return false;
  for (const char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  return true;
}

double number(const Xml& x, const pugi::xml_node& n, const char* attr, double fallback) {
  const pugi::xml_attribute a = n.attribute(attr);
  if (!a) return fallback;
  char* end = nullptr;
  const double v = std::strtod(a.value(), &end);
  if (end == a.value() || *end || !std::isfinite(v))
    x.fail(n, std::string("attribute ") + attr + "=\"" + a.value() + "\" is not a number");
  return v;
}

struct Unit {
  std::array<int, 8> exponents{};  // kg m s A K mol cd rad
  double factor = 1, offset = 0;
};

// SSP 1.0 parameter values (<ssv:Real value=...> etc.) into a YAML start map.
void read_parameters(const Xml& x, const pugi::xml_node& set, YAML::Node& start) {
  const pugi::xml_node params = child(set, "Parameters");
  for (const pugi::xml_node p : children(params, "Parameter")) {
    const std::string name = p.attribute("name").value();
    if (name.empty()) x.fail(p, "a <Parameter> without a name");
    pugi::xml_node value;
    for (const pugi::xml_node c : p.children())
      if (c.type() == pugi::node_element) {
        value = c;
        break;
      }
    const std::string type = value ? local(value) : "";
    if (type != "Real" && type != "Integer" && type != "Boolean" && type != "String" && type != "Enumeration")
      x.fail(p, "parameter '" + name + "' has no value of a supported type (Real, Integer, Boolean, String, Enumeration)");
    if (!value.attribute("value")) x.fail(value, "parameter '" + name + "': no value attribute");
    const std::string v = value.attribute("value").value();
    if (type == "Real") number(x, value, "value", 0);
    if (type == "Real" && value.attribute("unit"))
      x.fail(value, "parameter '" + name + "' has a unit (" + value.attribute("unit").value() +
                        "): parameter unit conversion is not supported; give the value in the FMU's unit without unit=");
    start[name] = v;
  }
}

void read_binding(const Xml& ssd, const pugi::xml_node& binding, const fs::path& base, YAML::Node& start) {
  if (const pugi::xml_attribute prefix = binding.attribute("prefix"); prefix && *prefix.value())
    ssd.fail(binding, std::string("ParameterBinding prefix=\"") + prefix.value() + "\" is not supported (bind to the component's own parameter names)");
  if (const pugi::xml_attribute source = binding.attribute("source")) {
    const std::string src = source.value();
    if (src.rfind("#", 0) == 0 || src.find("://") != std::string::npos)
      ssd.fail(binding, "ParameterBinding source=\"" + src + "\": only files in the package (relative paths) are supported");
    Xml ssv;
    load_xml(ssv, (base / src).lexically_normal().string(), ssd.at(binding));
    const pugi::xml_node set = ssv.doc.document_element();
    if (local(set) != "ParameterSet") ssv.fail(set, "the root element is <" + std::string(set.name()) + ">, not <ssv:ParameterSet>");
    read_parameters(ssv, set, start);
    return;
  }
  const pugi::xml_node values = child(binding, "ParameterValues");
  const pugi::xml_node set = child(values, "ParameterSet");
  if (!set) ssd.fail(binding, "a ParameterBinding needs source=\"file.ssv\" or inline <ssd:ParameterValues><ssv:ParameterSet>");
  read_parameters(ssd, set, start);
}

// An .ssp unpacked into $TMPDIR/cosim_ssp_<hash>/ (kept: the participants read the FMUs from
// there during the run, and a resumed run again).
std::string unpack(const std::string& ssp_path) {
  struct stat st {};
  if (stat(ssp_path.c_str(), &st) != 0) throw SspError(ssp_path + ": file not found");
  const std::string key = fs::absolute(ssp_path).string() + "|" + std::to_string(st.st_size) + "|" + std::to_string(st.st_mtime);
  char hex[32];
  std::snprintf(hex, sizeof hex, "%016zx", std::hash<std::string>{}(key));
  const char* tmp = std::getenv("TMPDIR");
  const fs::path dir = fs::path(tmp && *tmp ? tmp : "/tmp") / ("cosim_ssp_" + std::string(hex));
  if (fs::exists(dir / ".complete")) return dir.string();
  unzFile z = unzOpen64(ssp_path.c_str());
  if (!z) throw SspError(ssp_path + ": not a zip archive (an .ssp package is a zip with SystemStructure.ssd at its root)");
  const fs::path part = dir.string() + ".part" + std::to_string(::getpid());
  fs::remove_all(part);
  fs::create_directories(part);
  for (int rc = unzGoToFirstFile(z); rc == UNZ_OK; rc = unzGoToNextFile(z)) {
    unz_file_info64 info{};
    char name[4096];
    unzGetCurrentFileInfo64(z, &info, name, sizeof name, nullptr, 0, nullptr, 0);
    const std::string n = name;
    if (n.empty() || n[0] == '/' || n.find("..") != std::string::npos || n.find('\\') != std::string::npos) {
      unzClose(z);
      fs::remove_all(part);
      throw SspError(ssp_path + ": entry '" + n + "' would land outside the package folder");
    }
    if (n.back() == '/') {
      fs::create_directories(part / n);
      continue;
    }
    fs::create_directories((part / n).parent_path());
    std::string data(info.uncompressed_size, '\0');
    if (unzOpenCurrentFile(z) != UNZ_OK ||
        (!data.empty() && unzReadCurrentFile(z, data.data(), static_cast<unsigned>(data.size())) != static_cast<int>(data.size()))) {
      unzClose(z);
      fs::remove_all(part);
      throw SspError(ssp_path + ": entry '" + n + "' cannot be read (damaged archive)");
    }
    unzCloseCurrentFile(z);
    std::ofstream(part / n, std::ios::binary).write(data.data(), static_cast<std::streamsize>(data.size()));
  }
  unzClose(z);
  std::ofstream(part / ".complete") << ssp_path << "\n";
  std::error_code ec;
  fs::rename(part, dir, ec);
  if (ec) fs::remove_all(part);  // another process unpacked it first
  return dir.string();
}

struct Connector {
  std::string kind, unit;
  pugi::xml_node node;
};
struct Comp {
  YAML::Node params;
  std::map<std::string, Connector> connectors;
  std::map<std::string, std::size_t> input_index;  // connector -> index in params["inputs"]
};

// <ssd:Units>: each unit's base-unit exponents, factor and offset.
std::map<std::string, Unit> read_units(const Xml& ssd, const pugi::xml_node& root) {
  std::map<std::string, Unit> units;
  for (const pugi::xml_node u : children(child(root, "Units"), "Unit")) {
    Unit unit;
    const pugi::xml_node b = child(u, "BaseUnit");
    static const char* names[] = {"kg", "m", "s", "A", "K", "mol", "cd", "rad"};
    for (int i = 0; i < 8; ++i) unit.exponents[i] = static_cast<int>(number(ssd, b, names[i], 0));
    unit.factor = number(ssd, b, "factor", 1);
    unit.offset = number(ssd, b, "offset", 0);
    if (unit.factor == 0) ssd.fail(b, "unit '" + std::string(u.attribute("name").value()) + "' has factor 0");
    units[u.attribute("name").value()] = unit;
  }
  return units;
}

// One <ssd:Component> (an FMU) as the fmu_adapter parameters of a participant: the FMU, its
// start values and its input and output connectors. `comps` holds the ones read before it.
Comp read_component(const Xml& ssd, const pugi::xml_node& e, const fs::path& base,
                    const std::map<std::string, Unit>& units, const std::map<std::string, Comp>& comps) {
  if (local(e) != "Component")
    ssd.fail(e, "<" + std::string(e.name()) + ">: only FMU components are supported (no nested systems or signal dictionaries)");
  const std::string name = e.attribute("name").value();
  if (!valid_name(name))
    ssd.fail(e, "component name '" + name + "' is not a valid participant name (1..32 of A-Za-z0-9_)");
  if (comps.count(name)) ssd.fail(e, "component name '" + name + "' is used twice");
  const std::string type = e.attribute("type").value();
  if (!type.empty() && type != "application/x-fmu-sharedlibrary")
    ssd.fail(e, "component '" + name + "' has type \"" + type + "\": only FMUs (application/x-fmu-sharedlibrary) are supported");
  const std::string source = e.attribute("source").value();
  if (source.empty()) ssd.fail(e, "component '" + name + "' has no source (the FMU in the package)");
  const fs::path fmu = (base / source).lexically_normal();
  if (!fs::is_regular_file(fmu))
    ssd.fail(e, "component '" + name + "': its FMU " + source + " is missing (looked for " + fmu.string() + ")");
  Comp c;
  c.params = YAML::Node(YAML::NodeType::Map);
  c.params["fmu"] = fmu.string();
  YAML::Node start(YAML::NodeType::Map);
  for (const pugi::xml_node b : children(child(e, "ParameterBindings"), "ParameterBinding")) read_binding(ssd, b, base, start);
  if (start.size() > 0) c.params["start"] = start;
  YAML::Node inputs(YAML::NodeType::Sequence), outputs(YAML::NodeType::Sequence);
  for (const pugi::xml_node k : children(child(e, "Connectors"), "Connector")) {
    Connector con;
    con.node = k;
    const std::string cname = k.attribute("name").value();
    con.kind = k.attribute("kind").value();
    if (!valid_name(cname))
      ssd.fail(k, "connector '" + cname + "' of component '" + name + "': not a valid signal name (1..32 of A-Za-z0-9_)");
    for (const pugi::xml_node t : k.children())
      if (t.type() == pugi::node_element && local(t) == "Real") con.unit = t.attribute("unit").value();
    if (!con.unit.empty() && !units.count(con.unit))
      ssd.fail(k, "connector '" + name + "." + cname + "' has unit '" + con.unit + "', which <ssd:Units> does not define");
    if (con.kind == "input" || con.kind == "output") {
      YAML::Node port(YAML::NodeType::Map);
      port["name"] = cname;
      port["scalar"] = cname;
      if (con.kind == "input") {
        c.input_index[cname] = inputs.size();
        inputs.push_back(port);
      } else {
        outputs.push_back(port);
      }
    } else if (con.kind != "parameter" && con.kind != "calculatedParameter" && con.kind != "structuralParameter") {
      ssd.fail(k, "connector '" + name + "." + cname + "' has kind \"" + con.kind + "\": supported are input and output");
    }
    c.connectors[cname] = con;
  }
  c.params["inputs"] = inputs;
  c.params["outputs"] = outputs;
  return c;
}

// One <ssd:Connection> as a connection of the master's config, with the unit conversion put on
// the input port it feeds (factor, offset); `fed` holds the inputs fed so far.
YAML::Node read_connection(const Xml& ssd, const pugi::xml_node& k, std::map<std::string, Comp>& comps,
                           const std::map<std::string, Unit>& units, const std::string& predictor,
                           std::set<std::string>& fed) {
  const std::string se = k.attribute("startElement").value(), sc = k.attribute("startConnector").value();
  const std::string ee = k.attribute("endElement").value(), ec = k.attribute("endConnector").value();
  if (se.empty() || ee.empty())
    ssd.fail(k, "a connection to the system's own connectors (no startElement or endElement) is not supported");
  auto find = [&](const std::string& el, const std::string& con, const char* end) -> const Connector& {
    const auto c = comps.find(el);
    if (c == comps.end())
      ssd.fail(k, std::string("dangling connection: its ") + end + "Element '" + el + "' is not a component of the system");
    const auto n = c->second.connectors.find(con);
    if (n == c->second.connectors.end())
      ssd.fail(k, std::string("dangling connection: component '") + el + "' has no connector '" + con + "'");
    return n->second;
  };
  const Connector& from = find(se, sc, "start");
  const Connector& to = find(ee, ec, "end");
  if (from.kind != "output") ssd.fail(k, "connection " + se + "." + sc + " -> " + ee + "." + ec + ": its start is not an output connector");
  if (to.kind != "input") ssd.fail(k, "connection " + se + "." + sc + " -> " + ee + "." + ec + ": its end is not an input connector");
  if (!fed.insert(ee + "." + ec).second) ssd.fail(k, "input " + ee + "." + ec + " is the end of two connections");
  // Unit conversion (SSP 1.0, 5.3.x): an explicit <ssc:LinearTransformation>, else the
  // implicit one between the connectors' units: SI = factor * value + offset on each side.
  double factor = 1, offset = 0;
  if (const pugi::xml_node lt = child(k, "LinearTransformation")) {
    factor = number(ssd, lt, "factor", 1);
    offset = number(ssd, lt, "offset", 0);
  } else if (const pugi::xml_node uc = child(k, "UnitConversion")) {
    const std::string u = uc.attribute("unit").value();
    if (!units.count(u)) ssd.fail(uc, "<ssc:UnitConversion unit=\"" + u + "\">: <ssd:Units> does not define it");
    if (from.unit.empty() || to.unit.empty()) ssd.fail(uc, "a unit conversion needs units on both connectors");
  } else if (child(k, "MapTransformation") || child(k, "BooleanMappingTransformation") || child(k, "IntegerMappingTransformation")) {
    ssd.fail(k, "connection " + se + "." + sc + " -> " + ee + "." + ec + ": only linear transformations and unit conversions are supported");
  }
  if (!from.unit.empty() && !to.unit.empty() && from.unit != to.unit && !child(k, "LinearTransformation")) {
    const Unit& a = units.at(from.unit);
    const Unit& b = units.at(to.unit);
    if (a.exponents != b.exponents)
      ssd.fail(k, "connection " + se + "." + sc + " [" + from.unit + "] -> " + ee + "." + ec + " [" + to.unit +
                      "]: the units measure different quantities (their base-unit exponents differ)");
    factor = a.factor / b.factor;
    offset = (a.offset - b.offset) / b.factor;
  }
  YAML::Node conn(YAML::NodeType::Map);
  conn["from"] = se + "." + sc;
  conn["to"] = ee + "." + ec;
  if (!predictor.empty()) conn["predictor"] = predictor;
  if (factor != 1 || offset != 0) {
    YAML::Node port = comps[ee].params["inputs"][comps[ee].input_index[ec]];
    port["factor"] = factor;
    port["offset"] = offset;
  }
  return conn;
}

}  // namespace

bool is_system_file(const std::string& path) { return ends_with(path, ".ssp") || ends_with(path, ".ssd"); }

YAML::Node system_config(const std::string& path, const std::string& predictor) {
  std::string ssd_path = path;
  if (ends_with(path, ".ssp")) {
    const std::string dir = unpack(path);
    ssd_path = (fs::path(dir) / "SystemStructure.ssd").string();
    if (!fs::exists(ssd_path)) throw SspError(path + ": no SystemStructure.ssd at the root of the package");
  }
  Xml ssd;
  load_xml(ssd, ssd_path, "");
  if (ends_with(path, ".ssp")) ssd.path = path + "!/SystemStructure.ssd";  // messages name the package
  const fs::path base = fs::absolute(ssd_path).parent_path();
  const pugi::xml_node root = ssd.doc.document_element();
  if (local(root) != "SystemStructureDescription")
    ssd.fail(root, "the root element is <" + std::string(root.name()) + ">, not <ssd:SystemStructureDescription>");
  const std::string version = root.attribute("version").value();
  if (version.rfind("1.", 0) != 0) ssd.fail(root, "SSP version \"" + version + "\": cosim_master imports SSP 1.0");
  const pugi::xml_node system = child(root, "System");
  if (!system) ssd.fail(root, "no <ssd:System>");

  const std::map<std::string, Unit> units = read_units(ssd, root);
  std::map<std::string, Comp> comps;
  std::vector<std::string> order;
  YAML::Node config(YAML::NodeType::Map);
  for (const pugi::xml_node e : child(system, "Elements").children()) {
    if (e.type() != pugi::node_element) continue;
    Comp c = read_component(ssd, e, base, units, comps);  // checks the name is new
    comps[e.attribute("name").value()] = std::move(c);
    order.push_back(e.attribute("name").value());
  }
  if (comps.empty()) ssd.fail(system, "the system has no components");

  YAML::Node connections(YAML::NodeType::Sequence);
  std::set<std::string> fed;
  for (const pugi::xml_node k : children(child(system, "Connections"), "Connection"))
    connections.push_back(read_connection(ssd, k, comps, units, predictor, fed));

  YAML::Node time(YAML::NodeType::Map);
  if (const pugi::xml_node de = child(root, "DefaultExperiment")) {
    if (de.attribute("startTime")) time["start"] = number(ssd, de, "startTime", 0);
    if (de.attribute("stopTime")) time["end"] = number(ssd, de, "stopTime", 0);
  }
  if (time.size() > 0) config["time"] = time;
  YAML::Node participants(YAML::NodeType::Map);
  for (const auto& name : order) {
    YAML::Node p(YAML::NodeType::Map);
    YAML::Node launch(YAML::NodeType::Sequence);
    launch.push_back("fmu_adapter");
    p["launch"] = launch;
    p["parameters"] = comps[name].params;
    participants[name] = p;
  }
  config["participants"] = participants;
  config["connections"] = connections;
  return config;
}

YAML::Node load_root(const std::string& path, std::string* source_text) {
  YAML::Node root;
  if (is_system_file(path)) {
    root = system_config(path);
  } else {
    root = cosim::config::load_file(path);  // refuses folders, scalars, duplicate keys
    if (!root["ssp"]) {
      *source_text = slurp(path);
      return root;
    }
    const YAML::Node s = root["ssp"];
    std::string file, predictor;
    if (s.IsScalar()) {
      file = s.Scalar();
    } else if (s.IsMap()) {
      cosim::config::check_keys(s, "ssp", {"file", "predictor"});
      file = cosim::config::get_string(s, "ssp", "file");
      if (s["predictor"]) predictor = cosim::config::get_string(s, "ssp", "predictor");
    } else {
      throw cosim::config::ConfigError("ssp: expected FILE.ssd / FILE.ssp, or {file: ..., predictor: NAME}");
    }
    if (!is_system_file(file)) throw cosim::config::ConfigError("ssp: '" + file + "' is not an .ssp or .ssd file");
    const fs::path f = fs::path(file).is_absolute() ? fs::path(file) : fs::absolute(path).parent_path() / file;
    const YAML::Node sys = system_config(f.lexically_normal().string(), predictor);
    root.remove("ssp");
    if (!root["time"]) root["time"] = YAML::Node(YAML::NodeType::Map);
    if (sys["time"])
      for (const auto& kv : sys["time"])
        if (!root["time"][kv.first.Scalar()]) root["time"][kv.first.Scalar()] = kv.second;
    if (!root["participants"]) root["participants"] = YAML::Node(YAML::NodeType::Map);
    for (const auto& kv : sys["participants"]) {
      if (root["participants"][kv.first.Scalar()])
        throw cosim::config::ConfigError("participants." + kv.first.Scalar() + ": defined here and as a component of " + file);
      root["participants"][kv.first.Scalar()] = kv.second;
    }
    if (!root["connections"] || root["connections"].IsNull()) root["connections"] = YAML::Node(YAML::NodeType::Sequence);
    for (const auto& c : sys["connections"]) root["connections"].push_back(c);
  }
  YAML::Emitter out;
  out << root;
  *source_text = std::string("# generated by cosim_master from ") + path + " (SSP 1.0)\n" + out.c_str() + "\n";
  return YAML::Load(*source_text);
}

}  // namespace ssp
