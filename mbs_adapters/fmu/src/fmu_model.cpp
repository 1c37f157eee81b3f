#include "fmu_model.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <set>
#include <sstream>

#include "cosim/paths.hpp"
#include "cosim/yaml_config.hpp"

namespace fmu {

namespace cfg = cosim::config;
using cosim::SignalKind;
using cosim::Value;
namespace fs = std::filesystem;

namespace {

std::string emit(const YAML::Node& n) {
  YAML::Emitter out;
  out << n;
  return out.c_str();
}

bool is_number(const YAML::Node& n, double* v) {
  if (!n.IsScalar()) return false;
  try {
    *v = n.as<double>();
    return std::isfinite(*v);
  } catch (const YAML::Exception&) {
    return false;
  }
}

std::string allowed_list(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? "none" : s;
}

// The FMU's variables of some causalities, for "did you mean" lists.
std::string variables_with(const ModelDescription& md, std::initializer_list<Causality> cs) {
  std::vector<std::string> names;
  for (const auto& v : md.variables)
    for (Causality c : cs)
      if (v.causality == c && is_numeric(v.type) && v.dimensions.empty()) names.push_back(v.name);
  if (names.size() > 12) {
    names.resize(12);
    names.push_back("...");
  }
  return allowed_list(names);
}

cosim::Vec3 rotate(const cosim::Quat& q, const cosim::Vec3& v) { return cosim::quat_rotate(q, v); }
cosim::Vec3 rotate_back(const cosim::Quat& q, const cosim::Vec3& v) {
  return cosim::quat_rotate(cosim::quat_conjugate(q), v);
}

}  // namespace

FmuModel::FmuModel(YAML::Node root, std::string base_dir)
    : root_(root ? YAML::Clone(root) : YAML::Node(YAML::NodeType::Map)), base_dir_(std::move(base_dir)) {}

FmuModel::~FmuModel() {
  inst_.reset();
  lib_.reset();
  lib3_.reset();
  unpacked_.reset();
}

const Variable& FmuModel::variable(const std::string& name, const std::string& path) const {
  const Variable* v = md_->find(name);
  if (!v) {
    std::string near;
    for (const auto& x : md_->variables)
      if (!cfg::closest_key(name, {x.name}).empty()) near = x.name;
    throw cfg::ConfigError(path + ": FMU " + label_ + " has no variable '" + name + "'" +
                           (near.empty() ? std::string() : "; did you mean '" + near + "'?") +
                           " (its inputs: " + variables_with(*md_, {Causality::Input}) +
                           "; outputs: " + variables_with(*md_, {Causality::Output}) +
                           "; parameters: " + variables_with(*md_, {Causality::Parameter}) + ")");
  }
  return *v;
}

// Ports carry numbers, one per variable or array element.
void check_port_variable(const Variable& v, const std::string& path, long long element) {
  if (!is_numeric(v.type))
    throw cfg::ConfigError(path + ": '" + v.name + "' is a " + type_name(v.type) +
                           " variable; ports carry numbers (Real, Integer, Boolean, Enumeration; FMI 3.0: Float32/64, "
                           "Int8 ... UInt64, Boolean, Enumeration); set String and Binary values under `start`");
  if (!v.dimensions.empty() && element < 0)
    throw cfg::ConfigError(path + ": '" + v.name + "' is an array (" + std::to_string(v.dimensions.size()) +
                           " <Dimension>); a port carries one number: name an element, e.g. " + v.name + "[1]" +
                           (v.dimensions.size() > 1 ? std::string(" ... [1,1]") : std::string()) + " (1-based)");
}

const Variable& FmuModel::element_variable(const std::string& name, const std::string& path, long long* element) const {
  *element = -1;
  const auto open = name.find('[');
  if (open == std::string::npos || name.back() != ']' || md_->find(name)) return variable(name, path);
  const Variable& v = variable(name.substr(0, open), path);
  if (v.dimensions.empty())
    throw cfg::ConfigError(path + ": '" + v.name + "' is not an array; name it without [...]");
  std::vector<long long> index;
  std::stringstream list(name.substr(open + 1, name.size() - open - 2));
  std::string part;
  while (std::getline(list, part, ',')) {
    char* end = nullptr;
    const long long i = std::strtoll(part.c_str(), &end, 10);
    if (part.empty() || *end || i < 1)
      throw cfg::ConfigError(path + ": '" + name + "': indices are whole numbers from 1, e.g. " + v.name + "[1]");
    index.push_back(i);
  }
  if (index.size() != v.dimensions.size())
    throw cfg::ConfigError(path + ": '" + name + "': '" + v.name + "' has " + std::to_string(v.dimensions.size()) +
                           " dimension(s), so give " + std::to_string(v.dimensions.size()) + " index(es)");
  const std::vector<std::size_t> dims = array_dims(v);
  long long flat = 0;
  for (std::size_t d = 0; d < dims.size(); ++d) {
    if (index[d] > static_cast<long long>(dims[d]))
      throw cfg::ConfigError(path + ": '" + name + "': index " + std::to_string(index[d]) + " is beyond the size " +
                             std::to_string(dims[d]) + " of dimension " + std::to_string(d + 1));
    flat = flat * static_cast<long long>(dims[d]) + (index[d] - 1);
  }
  *element = flat;
  return v;
}

std::vector<std::size_t> FmuModel::array_dims(const Variable& v) const {
  std::vector<std::size_t> dims;
  for (const auto& d : v.dimensions) {
    if (d.start) {
      dims.push_back(static_cast<std::size_t>(*d.start));
      continue;
    }
    const Variable* param = md_->find_by_reference(*d.value_reference);
    double n = -1;
    if (inst_) {
      n = inst_->get_number(*param, "(the size of '" + v.name + "')");
    } else {
      for (const auto& sv : start_values_)
        if (sv.var == param) n = sv.value.number;
      if (n < 0 && param->start) n = std::strtod(param->start->c_str(), nullptr);
    }
    if (!(n >= 0)) throw FmuError("FMU " + label_ + ": the size of array '" + v.name + "' (structural parameter '" + param->name + "') is not known");
    dims.push_back(static_cast<std::size_t>(n));
  }
  return dims;
}

std::size_t FmuModel::array_size(const Variable& v) const {
  std::size_t n = 1;
  for (const std::size_t d : array_dims(v)) n *= d;
  return n;
}


Component FmuModel::output_component(const YAML::Node& node, const std::string& path) const {
  Component c;
  double x = 0;
  if (is_number(node, &x)) {
    c.constant = x;
    return c;
  }
  if (!node.IsScalar())
    throw cfg::ConfigError(path + ": expected an FMU variable name or a number");
  long long element = -1;
  const Variable& v = element_variable(node.Scalar(), path, &element);
  c.element = element;
  check_port_variable(v, path, element);
  if (v.causality == Causality::Input)
    throw cfg::ConfigError(path + ": '" + v.name + "' has causality input; an output port reads variables with causality output (or local, parameter)");
  if (v.causality == Causality::Independent)
    throw cfg::ConfigError(path + ": '" + v.name + "' is the independent variable (time); the master knows the time");
  c.var = &v;
  return c;
}

Component FmuModel::input_component(const YAML::Node& node, const std::string& path) const {
  Component c;
  if (!node || node.IsNull()) return c;  // this number of the signal is not passed on
  double x = 0;
  if (is_number(node, &x) || !node.IsScalar())
    throw cfg::ConfigError(path + ": an input port sets FMU variables: give a variable name, or null to leave this number out");
  long long element = -1;
  const Variable& v = element_variable(node.Scalar(), path, &element);
  c.element = element;
  check_port_variable(v, path, element);
  if (v.causality != Causality::Input)
    throw cfg::ConfigError(path + ": '" + v.name + "' has causality " + causality_name(v.causality) +
                           "; an input port sets variables with causality input" +
                           (v.causality == Causality::Parameter ? std::string(" (set parameters under `start`)") : std::string()));
  c.var = &v;
  return c;
}

PortMap FmuModel::parse_port(const YAML::Node& node, const std::string& path, bool input) {
  PortMap p;
  p.input = input;
  p.path = path;
  cfg::check_keys(node, path, {"name", "scalar", "kinematics", "wrench", "factor", "offset"});
  p.name = cfg::get_string(node, path, "name");
  cosim::require_valid_name(p.name, path + ".name");
  const int kinds = (node["scalar"] ? 1 : 0) + (node["kinematics"] ? 1 : 0) + (node["wrench"] ? 1 : 0);
  if (kinds != 1)
    throw cfg::ConfigError(path + ": give exactly one of scalar (a variable), kinematics or wrench (a map of variables)");
  auto comp = [&](const YAML::Node& n, const std::string& where) {
    return input ? input_component(n, where) : output_component(n, where);
  };
  auto vec = [&](const YAML::Node& m, const std::string& where, const std::string& key, bool outputs_style,
                 std::size_t size = 3) {
    std::vector<Component> out(size);
    const YAML::Node n = m[key];
    const std::string k = where + "." + key;
    if (!n || n.IsNull()) return out;  // outputs: zeros; inputs: not passed on
    if (!n.IsSequence() || n.size() != size)
      throw cfg::ConfigError(k + ": expected a list of " + std::to_string(size) +
                             " entries (FMU variable names" + (input && !outputs_style ? ", or null" : ", or numbers") + ")");
    for (std::size_t i = 0; i < size; ++i)
      out[i] = outputs_style ? output_component(n[i], k + "." + std::to_string(i)) : comp(n[i], k + "." + std::to_string(i));
    return out;
  };
  auto vec3 = [&](const YAML::Node& m, const std::string& where, const std::string& key, bool outputs_style) {
    const auto v = vec(m, where, key, outputs_style);
    return Vec3Map{v[0], v[1], v[2]};
  };
  if ((node["factor"] || node["offset"]) && !node["scalar"])
    throw cfg::ConfigError(path + ": factor and offset convert the unit of a scalar port only (kinematics and wrenches are SI)");
  if (node["scalar"]) {
    p.kind = SignalKind::Scalar;
    if (node["scalar"].IsNull()) throw cfg::ConfigError(path + ".scalar: expected an FMU variable name");
    p.scalar = comp(node["scalar"], path + ".scalar");
    if (node["factor"]) {
      p.scalar.factor = cfg::get_double(node, path, "factor");
      if (p.scalar.factor == 0) throw cfg::ConfigError(path + ".factor: must not be 0 (a unit conversion multiplies by it)");
    }
    if (node["offset"]) p.scalar.offset = cfg::get_double(node, path, "offset");
    if (!p.scalar.var && !input)
      throw cfg::ConfigError(path + ".scalar: expected an FMU variable name (a constant output says nothing)");
  } else if (node["kinematics"]) {
    p.kind = SignalKind::Kinematics;
    const YAML::Node k = node["kinematics"];
    const std::string kp = path + ".kinematics";
    cfg::check_keys(k, kp, {"position", "orientation", "velocity", "angular_velocity", "angular_velocity_frame"});
    p.position = vec3(k, kp, "position", false);
    p.velocity = vec3(k, kp, "velocity", false);
    p.angular_velocity = vec3(k, kp, "angular_velocity", false);
    p.angular_velocity_in_body =
        cfg::get_choice(k, kp, "angular_velocity_frame", {"ground", "body"}, "ground") == "body";
    if (const YAML::Node o = k["orientation"]; o && !o.IsNull()) {
      const std::string op = kp + ".orientation";
      cfg::check_keys(o, op, {"quaternion", "angles", "sequence"});
      if (o["quaternion"] && o["angles"])
        throw cfg::ConfigError(op + ": give quaternion or angles, not both");
      if (o["quaternion"]) {
        p.orientation = OrientationMap::Quaternion;
        const auto q = vec(o, op, "quaternion", false, 4);
        for (int i = 0; i < 4; ++i) p.quaternion[i] = q[i];
        if (input && !p.quaternion[0].var) p.quaternion[0].constant = 1;  // read back: identity
        if (o["sequence"]) throw cfg::ConfigError(op + ".sequence: only with angles");
      } else if (o["angles"]) {
        p.orientation = OrientationMap::Angles;
        const auto a = vec(o, op, "angles", false);
        for (int i = 0; i < 3; ++i) p.angles[i] = a[i];
        const std::string seq = cfg::get_string(o, op, "sequence");
        try {
          p.sequence = parse_sequence(seq);
        } catch (const std::invalid_argument& e) {
          throw cfg::ConfigError(op + ".sequence: " + e.what() +
                                 " (allowed: body-fixed axis sequences such as zyx, xyz, zxz, zyz)");
        }
      } else {
        throw cfg::ConfigError(op + ": give quaternion: [w, x, y, z] or angles: [a0, a1, a2] with sequence");
      }
    }
  } else {
    p.kind = SignalKind::Wrench;
    const YAML::Node w = node["wrench"];
    const std::string wp = path + ".wrench";
    cfg::check_keys(w, wp, {"force", "torque", "frame", "reference_point"});
    p.force = vec3(w, wp, "force", false);
    p.torque = vec3(w, wp, "torque", false);
    if (!w["frame"])
      throw cfg::ConfigError(wp + ".frame: missing; state the axes the force and torque variables are in: "
                             "ground, or the name of a kinematics port (that body's axes)");
    const std::string frame = cfg::get_string(w, wp, "frame");
    if (frame != "ground") p.frame_port = frame;
    const YAML::Node rp = w["reference_point"];
    if (!rp)
      throw cfg::ConfigError(wp + ".reference_point: missing; state the point the torque is about: [x, y, z] in "
                             "ground coordinates (numbers or FMU variables), or the name of a kinematics port (its position)");
    double number = 0;
    if (rp.IsScalar() && !is_number(rp, &number)) {
      p.point_port = rp.Scalar();
    } else {
      // An input port may name three FMU inputs: the FMU takes the point with the wrench.
      if (input && rp.IsSequence())
        for (const auto& e : rp)
          if (e.IsScalar() && !is_number(e, &number) && md_->find(e.Scalar()) &&
              md_->find(e.Scalar())->causality == Causality::Input)
            p.point_is_input = true;
      p.point = vec3(w, wp, "reference_point", !p.point_is_input);
      if (p.point_is_input)
        for (std::size_t i = 0; i < 3; ++i)
          if (!p.point[i].var)
            throw cfg::ConfigError(wp + ".reference_point." + std::to_string(i) +
                                   ": a reference point set as FMU inputs needs all three (x, y, z) variables");
    }
  }
  return p;
}

void FmuModel::check_start_values(const YAML::Node& start, const std::string& path) {
  start_values_.clear();
  if (!start || start.IsNull()) return;
  if (!start.IsMap()) throw cfg::ConfigError(path + ": expected a map {variable name: value}");
  for (const auto& kv : start) {
    const std::string name = kv.first.as<std::string>();
    const std::string k = path + "." + name;
    const Variable& v = variable(name, k);
    if (v.causality == Causality::Independent)
      throw cfg::ConfigError(k + ": '" + name + "' is the independent variable (time); set time.start in the master's config");
    if (v.variability == Variability::Constant)
      throw cfg::ConfigError(k + ": '" + name + "' has variability constant; it cannot be set");
    if (v.causality == Causality::CalculatedParameter || v.initial == Initial::Calculated)
      throw cfg::ConfigError(k + ": '" + name + "' is calculated by the FMU (causality " + causality_name(v.causality) +
                             ", initial " + initial_name(v.initial) + "); only parameters, inputs and variables "
                             "with initial exact or approx take a start value");
    const YAML::Node val = kv.second;
    Scalar s;
    const std::string got = val.IsScalar() ? "'" + val.Scalar() + "'" : std::string("a list or map");
    auto wrong = [&](const std::string& expected) {
      return cfg::ConfigError(k + ": '" + name + "' is an FMI " + type_name(v.type) + " variable; expected " +
                              expected + ", got " + got);
    };
    if (!v.dimensions.empty()) {
      // An array: a list of its values, row-major, each checked as the type's scalar; the size
      // is checked below, once a structural parameter in the same map is known.
      if (!val.IsSequence()) throw wrong("a list of its values (it is an array)");
      if (!is_numeric(v.type)) throw wrong("numbers: fmu_adapter sets numeric arrays only");
      StartValue sv{&v, s, k, {}};
      for (std::size_t i = 0; i < val.size(); ++i) {
        const std::string ek = k + "." + std::to_string(i);
        double x = 0;
        if (v.type == VarType::Boolean) {
          try {
            x = val[i].as<bool>() ? 1 : 0;
          } catch (const YAML::Exception&) {
            throw cfg::ConfigError(ek + ": expected true or false");
          }
        } else if (!is_number(val[i], &x)) {
          throw cfg::ConfigError(ek + ": expected a finite number");
        } else if (is_integer(v.type)) {
          long double lo = 0, hi = 0;
          integer_range(v.type == VarType::Enumeration ? VarType::Int64 : v.type, &lo, &hi);
          if (x != std::nearbyint(x) || x < lo || x > hi)
            throw cfg::ConfigError(ek + ": expected an integer in the " + type_name(v.type) + " range, got " + val[i].Scalar());
        }
        sv.array.push_back(x);
      }
      start_values_.push_back(std::move(sv));
      continue;
    }
    if (!val.IsScalar()) throw wrong("a single value");
    if (is_float(v.type)) {
      if (!is_number(val, &s.number)) throw wrong("a finite number");
      if (v.type == VarType::Float32 && std::abs(s.number) > std::numeric_limits<float>::max())
        throw wrong("a number within the Float32 range");
    } else if (is_integer(v.type) && v.type != VarType::Enumeration) {
      long double lo = 0, hi = 0;
      integer_range(v.type, &lo, &hi);
      const std::string text = val.Scalar();
      // Digits only (a sign for signed types): "2.5", "1e3", "true" are not integers.
      const std::size_t first = !text.empty() && (text[0] == '-' || text[0] == '+') ? 1 : 0;
      if (text.size() == first || text.find_first_not_of("0123456789", first) != std::string::npos)
        throw wrong(v.type == VarType::Integer ? std::string("an integer") : "an integer (" + std::string(type_name(v.type)) + ")");
      errno = 0;
      const long double n = std::strtold(text.c_str(), nullptr);
      if (n < lo || n > hi) {
        char range[96];
        std::snprintf(range, sizeof range, "an integer from %.0Lf to %.0Lf", lo, hi);
        throw wrong(v.type == VarType::Integer ? std::string("an integer in the 32-bit range") : std::string(range));
      }
      s.number = static_cast<double>(n);
      if (v.type == VarType::UInt64) s.uint64 = std::strtoull(text.c_str() + (text[0] == '+'), nullptr, 10);
      else if (v.type == VarType::Int64) s.int64 = std::strtoll(text.c_str(), nullptr, 10);
    } else {
      switch (v.type) {
        case VarType::Boolean: {
          bool b = false;
          try {
            b = val.as<bool>();
          } catch (const YAML::Exception&) {
            throw wrong("true or false");
          }
          s.number = b ? 1 : 0;
          break;
        }
        case VarType::String:
          s.text = val.Scalar();
          break;
        case VarType::Binary: {
          s.text = val.Scalar();
          if (s.text.size() % 2 || s.text.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
            throw wrong("hex digits, two per byte (e.g. 666f6f)");
          break;
        }
        case VarType::Enumeration: {
          const auto items = md_->enumerations.find(v.declared_type);
          long long n = 0;
          bool ok = false;
          try {
            n = val.as<long long>();
            ok = val.Scalar().find_first_of(".eE") == std::string::npos;
          } catch (const YAML::Exception&) {
          }
          if (!ok && items != md_->enumerations.end()) {
            const auto it = items->second.find(val.Scalar());
            if (it != items->second.end()) {
              n = it->second;
              ok = true;
            }
          }
          if (!ok) {
            std::vector<std::string> names;
            if (items != md_->enumerations.end())
              for (const auto& [item, value] : items->second) names.push_back(item + " (" + std::to_string(value) + ")");
            throw wrong("an item of " + v.declared_type + ": " + allowed_list(names));
          }
          s.number = static_cast<double>(n);
          s.int64 = n;
          break;
        }
        default:
          throw cfg::ConfigError(k + ": '" + name + "' is an FMI " + type_name(v.type) + " variable; fmu_adapter does not set " +
                                 type_name(v.type) + " variables");
      }
    }
    start_values_.push_back({&v, s, k, {}});
  }
  for (const auto& sv : start_values_)
    if (!sv.var->dimensions.empty() && sv.array.size() != array_size(*sv.var))
      throw cfg::ConfigError(sv.key + ": '" + sv.var->name + "' has " + std::to_string(array_size(*sv.var)) +
                             " values, the list " + std::to_string(sv.array.size()));
}

void FmuModel::set_start_values() {
  for (const auto& sv : start_values_)
    if (sv.var->causality != Causality::StructuralParameter)  // set in Configuration Mode
    {
      if (sv.var->dimensions.empty()) inst_->set(*sv.var, sv.value, "(start value from " + sv.key + ")");
      else inst_->set_array(*sv.var, sv.array, "(start value from " + sv.key + ")");
    }
}

void FmuModel::parse_mapping(const YAML::Node& root, const std::string& path) {
  // path is "" for the adapter's own file at start-up (keys then stand alone)
  auto key = [&](const std::string& k) { return cfg::join_path(path, k); };
  instance_name_ = cfg::get_string_or(root, path, "instance", participant_);
  if (instance_name_.empty()) throw cfg::ConfigError(key("instance") + ": must not be empty");
  step_size_s_.reset();
  substeps_ = 0;
  if (root["step_size"] && root["substeps"])
    throw cfg::ConfigError((path.empty() ? std::string("mapping") : path) + ": give step_size or substeps, not both");
  if (root["step_size"]) step_size_s_ = cfg::get_positive(root, path, "step_size");
  if (root["substeps"]) {
    substeps_ = cfg::get_int(root, path, "substeps");
    if (substeps_ < 1 || substeps_ > 1000000)
      throw cfg::ConfigError(key("substeps") + ": " + std::to_string(substeps_) + " is not allowed (allowed: 1 to 1000000)");
  }
  tolerance_.reset();
  if (root["tolerance"]) tolerance_ = cfg::get_positive(root, path, "tolerance");
  verbose_ = cfg::get_bool_or(root, path, "verbose", false);
  snapshots_ = cfg::get_bool_or(root, path, "snapshots", true);
  input_derivatives_ = cfg::get_bool_or(root, path, "input_derivatives", true);
  start_ = root["start"] ? YAML::Clone(root["start"]) : YAML::Node();
  if (start_ && !start_.IsNull() && !start_.IsMap())
    throw cfg::ConfigError(key("start") + ": expected a map {variable name: value}");
  // Names, kinds and values now (also at start-up, without a master); set once instantiated.
  check_start_values(start_, key("start"));
  inputs_.clear();
  outputs_.clear();
  std::set<std::string> names;
  for (const bool input : {true, false}) {
    const std::string key_name = input ? "inputs" : "outputs";
    const YAML::Node list = root[key_name];
    if (!list || list.IsNull()) continue;
    if (!list.IsSequence()) throw cfg::ConfigError(key(key_name) + ": expected a list of ports {name, scalar|kinematics|wrench}");
    for (std::size_t i = 0; i < list.size(); ++i) {
      PortMap p = parse_port(list[i], key(key_name) + "." + std::to_string(i), input);
      if (!names.insert(p.name).second)
        throw cfg::ConfigError(p.path + ".name: '" + p.name + "' is used twice (input and output names share one list)");
      (input ? inputs_ : outputs_).push_back(std::move(p));
    }
  }
  if (outputs_.empty())
    throw cfg::ConfigError(key("outputs") + ": missing; map at least one FMU output to a port (FMU " + label_ +
                           " has outputs: " + variables_with(*md_, {Causality::Output}) + ")");
  auto kinematics_port = [&](const std::string& name, const std::string& where) {
    for (const auto* list : {&inputs_, &outputs_})
      for (const auto& p : *list)
        if (p.name == name) {
          if (p.kind != SignalKind::Kinematics)
            throw cfg::ConfigError(where + ": port '" + name + "' is not a kinematics port");
          return;
        }
    throw cfg::ConfigError(where + ": '" + name + "' is neither ground nor a kinematics port of this mapping");
  };
  // One input variable set by two ports would take whichever comes last.
  std::map<std::pair<const Variable*, long long>, std::string> set_by;
  for (auto* list : {&inputs_, &outputs_})
    for (auto& p : *list) {
      if (p.kind == SignalKind::Wrench) {
        if (!p.frame_port.empty()) kinematics_port(p.frame_port, p.path + ".wrench.frame");
        if (!p.point_port.empty()) kinematics_port(p.point_port, p.path + ".wrench.reference_point");
      }
      if (!p.input) continue;
      std::vector<const Component*> comps{&p.scalar};
      std::vector<const Vec3Map*> vecs{&p.position, &p.velocity, &p.angular_velocity, &p.force, &p.torque};
      if (p.point_is_input) vecs.push_back(&p.point);
      for (const auto* v : vecs)
        for (auto& c : *v) comps.push_back(&c);
      for (auto& c : p.quaternion) comps.push_back(&c);
      for (auto& c : p.angles) comps.push_back(&c);
      for (const auto* c : comps)
        if (c->var && !set_by.emplace(std::make_pair(c->var, c->element), p.name).second)
          throw cfg::ConfigError(p.path + ": FMU input '" + c->var->name + "' is set by port '" + set_by[{c->var, c->element}] +
                                 "' already");
    }
}

void FmuModel::prepare(const YAML::Node& parameters, const std::string& participant, bool own_file) {
  participant_ = participant;
  const std::string path = own_file ? std::string() : "participants." + participant + ".parameters";
  YAML::Node root = YAML::Clone(root_);
  if (parameters && parameters.IsMap()) cfg::apply_overrides(root, parameters, path);
  cfg::check_keys(root, path, {"fmu", "instance", "step_size", "substeps", "tolerance", "start", "inputs",
                               "outputs", "verbose", "snapshots", "input_derivatives"});
  const std::string text = emit(root);
  if (md_ && text == prepared_yaml_) return;  // the same mapping: keep the loaded FMU
  inst_.reset();
  lib_.reset();
  lib3_.reset();
  md_.reset();
  unpacked_.reset();
  const std::string given = cfg::get_string(root, path, "fmu");
  fmu_path_ = cosim::input_path(base_dir_, given);
  label_ = fs::path(fmu_path_).filename().string();
  unpacked_ = std::make_unique<UnpackedFmu>(fmu_path_);
  bool found = false;
  const std::string xml = unpacked_->read("modelDescription.xml", &found);
  if (!found)
    throw FmuError("FMU '" + label_ + "': no modelDescription.xml at the top of the archive; not an FMU (or a folder was zipped around it)");
  md_ = std::make_unique<ModelDescription>(parse_model_description(xml, label_));
  label_ = fs::path(fmu_path_).filename().string() + " (model '" + md_->model_name + "')";
  // FMI 2.0: binaries/linux64; FMI 3.0: binaries/x86_64-linux (<architecture>-<os>).
  const std::string platform = md_->fmi_major == 3 ? "x86_64-linux" : "linux64";
  const std::string folder = "binaries/" + platform + "/";
  const std::string so = folder + md_->model_identifier + ".so";
  const fs::path so_path = fs::path(unpacked_->dir()) / so;
  if (!fs::exists(so_path)) {
    // The platform folder may hold a library of another name: then the modelIdentifier is wrong
    // (or the FMU was renamed by hand), not the platform.
    std::vector<std::string> here;
    for (const auto& e : unpacked_->entries())
      if (e.rfind(folder, 0) == 0 && e.size() > folder.size() && e.back() != '/') here.push_back(e.substr(folder.size()));
    if (!here.empty())
      throw FmuError("FMU '" + label_ + "': <CoSimulation modelIdentifier=\"" + md_->model_identifier +
                     "\"> in modelDescription.xml names the binary " + so + ", which is not in the archive; " +
                     folder + " holds " + allowed_list(here) +
                     ". The modelIdentifier must be the binary's file name without .so: the FMU is "
                     "inconsistent (renamed by hand?); export it again, or repack it with the binary named " +
                     md_->model_identifier + ".so");
    std::set<std::string> platforms;
    for (const auto& e : unpacked_->entries())
      if (e.rfind("binaries/", 0) == 0) {
        const auto slash = e.find('/', 9);
        if (slash != std::string::npos) platforms.insert(e.substr(9, slash - 9));
      }
    std::string list;
    for (const auto& p : platforms) list += (list.empty() ? "" : ", ") + p;
    throw FmuError("FMU '" + label_ + "': no binary for this platform: " + so + " is not in the archive (" +
                   (list.empty() ? std::string("it has no binaries at all")
                                 : "it has binaries for: " + list) +
                   "); export the FMU for " + platform + " (x86_64 Linux) from its tool");
  }
  if (md_->needs_execution_tool)
    std::cerr << "fmu_adapter " << participant_ << ": FMU " << label_
              << " declares needsExecutionTool=\"true\": its tool must be installed and licensed on this host\n";
  if (md_->fmi_major == 3) {
    lib3_ = std::make_unique<Fmi3Library>(so_path.string(), label_);
    lib_state_ = lib3_->has_state_functions();
    lib_serialize_ = lib3_->has_serialize_functions();
  } else {
    lib_ = std::make_unique<Fmi2Library>(so_path.string(), label_);
    lib_state_ = lib_->has_state_functions();
    lib_serialize_ = lib_->has_serialize_functions();
  }
  parse_mapping(root, path);
  prepared_yaml_ = text;
}

void FmuModel::configure(const YAML::Node& parameters, const cosim::RunInfo& run) {
  try {
    configure_instance(parameters, run);
  } catch (...) {
    // Refused: let go of the FMU and its unpacked folder now. A refused participant is not in
    // the session and may be killed rather than told to stop.
    inst_.reset();
    lib_.reset();
    lib3_.reset();
    md_.reset();
    unpacked_.reset();
    prepared_yaml_.clear();
    throw;
  }
}

void FmuModel::configure_instance(const YAML::Node& parameters, const cosim::RunInfo& run) {
  prepare(parameters, run.participant);
  inst_.reset();  // a new run starts from a new instance
  received_.clear();
  const std::string path = "participants." + run.participant + ".parameters";
  if (step_size_s_) {
    inner_step_ = cosim::seconds_to_duration(*step_size_s_, path + ".step_size");
  } else if (substeps_ > 0) {
    if (run.macro_step % substeps_ != cosim::Duration::zero())
      throw cfg::ConfigError(path + ".substeps: the macro step of " + std::to_string(cosim::to_ns(run.macro_step)) +
                             " ns does not split into " + std::to_string(substeps_) +
                             " sub-steps of whole nanoseconds; choose another number or step_size");
    inner_step_ = run.macro_step / substeps_;
  } else {
    inner_step_ = run.macro_step;  // one doStep per macro step
  }
  if (inner_step_ <= cosim::Duration::zero()) throw cfg::ConfigError(path + ".step_size: must be at least 1 ns");
  if (run.macro_step % inner_step_ != cosim::Duration::zero())
    throw cfg::ConfigError(path + ".step_size: " + std::to_string(cosim::to_seconds(inner_step_)) +
                           " s does not divide the macro step " + std::to_string(cosim::to_seconds(run.macro_step)) +
                           " s; choose a step size that does, or substeps: N");
  // FMI 3.0 fixedInternalStepSize: the FMU integrates with that step; a doStep that is not a
  // whole number of them makes it end the step with a shorter one (or interpolate). Said, not
  // refused: it is the FMU's business, and the result may still be what the user wants.
  if (md_->fixed_internal_step_size && *md_->fixed_internal_step_size > 0) {
    const double h = cosim::to_seconds(inner_step_), n = h / *md_->fixed_internal_step_size;
    if (std::abs(n - std::nearbyint(n)) > 1e-9 * std::max(1.0, n) || std::nearbyint(n) < 1)
      std::cerr << "fmu_adapter " << participant_ << ": note: FMU " << label_ << " integrates with a fixed internal step of "
                << *md_->fixed_internal_step_size << " s (fixedInternalStepSize); its doStep of " << h
                << " s is not a whole number of them, so each step ends with a shorter one: choose a macro step or "
                   "step_size that is a multiple of it\n";
  }
  const std::string who = "fmu_adapter " + participant_ + ": ";
  auto sink = [who](const std::string& line) { std::cerr << who << line << "\n"; };
  const std::string resources_dir = (fs::path(unpacked_->dir()) / "resources").string() + "/";
  if (md_->fmi_major == 3) {
    // FMI 3.0 takes the resources folder as a native path. Structural parameters are set in
    // Configuration Mode, the other start values after it (FMI 3.0, 2.3.2).
    auto inst = std::make_unique<Fmi3Instance>(*lib3_, *md_, label_, instance_name_, resources_dir, verbose_, sink);
    bool structural = false;
    for (const auto& sv : start_values_) structural = structural || sv.var->causality == Causality::StructuralParameter;
    if (structural) {
      inst->enter_configuration();
      for (const auto& sv : start_values_)
        if (sv.var->causality == Causality::StructuralParameter)
          inst->set(*sv.var, sv.value, "(start value from " + sv.key + ")");
      inst->exit_configuration();
    }
    inst_ = std::move(inst);
  } else {
    // A URI (RFC 3986): the path percent-encoded, so a folder with a space or a '%' arrives intact.
    inst_ = std::make_unique<Fmi2Instance>(*lib_, *md_, label_, instance_name_, file_uri(resources_dir), verbose_, sink);
  }
  set_start_values();
  inst_->enter_initialization(cosim::to_seconds(run.t_start), tolerance_, cosim::to_seconds(run.t_end));
  inst_->exit_initialization();
}

cosim::Ports FmuModel::inputs() const {
  cosim::Ports out;
  for (const auto& p : inputs_) out.push_back({p.name, p.kind});
  return out;
}

cosim::Ports FmuModel::outputs() const {
  cosim::Ports out;
  for (const auto& p : outputs_) out.push_back({p.name, p.kind});
  return out;
}

bool FmuModel::can_repeat() const {
  return snapshots_ && md_ && md_->can_get_and_set_fmu_state && lib_state_;
}

std::string FmuModel::repeat_note() const {
  if (!md_) return "";
  if (!md_->can_get_and_set_fmu_state)
    return "FMU " + label_ + " declares " + state_attribute() + "=\"false\" (or leaves it out): it cannot save and "
           "restore its state, so it cannot repeat a step";
  if (!lib_state_)
    return "FMU " + label_ + " declares " + state_attribute() + "=\"true\" but its binary lacks " +
           (md_->fmi_major == 3 ? "fmi3GetFMUState, fmi3SetFMUState or fmi3FreeFMUState"
                                : "fmi2GetFMUstate, fmi2SetFMUstate or fmi2FreeFMUstate");
  if (!snapshots_) return "its mapping sets snapshots: false";
  return "";
}

bool FmuModel::can_checkpoint() const {
  return md_ && md_->can_get_and_set_fmu_state && md_->can_serialize_fmu_state && lib_serialize_;
}

// A checkpoint file: a header line, the GUID (a state of another FMU is refused), the adapter's
// highest input-derivative order so far, the size and the FMU's serialized state.
namespace {
constexpr const char* kCheckpointHeader = "fmu_adapter checkpoint 1";
}

void FmuModel::save_checkpoint(const std::string& path) {
  if (!can_checkpoint())
    throw FmuError("FMU " + label_ + " cannot serialize its state (" + serialize_attribute() + "=\"false\" or missing functions)");
  const std::string bytes = inst_->serialize_state();
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << kCheckpointHeader << "\n" << md_->guid << "\n" << max_derivative_order_ << "\n" << bytes.size() << "\n";
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.flush();
  if (!out) throw FmuError("cannot write checkpoint '" + path + "'");
}

void FmuModel::load_checkpoint(const std::string& path) {
  if (!can_checkpoint())
    throw FmuError("FMU " + label_ + " cannot deserialize a state (" + serialize_attribute() + "=\"false\" or missing functions)");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FmuError("cannot open checkpoint '" + path + "'");
  std::string header, guid, order, size;
  std::getline(in, header);
  std::getline(in, guid);
  std::getline(in, order);
  std::getline(in, size);
  if (header != kCheckpointHeader) throw FmuError("'" + path + "' is not a checkpoint of fmu_adapter");
  if (guid != md_->guid)
    throw FmuError("checkpoint '" + path + "' is of an FMU with GUID " + guid + ", but FMU " + label_ + " has " +
                   md_->guid + ": resume with the FMU the run started with");
  std::size_t n = 0;
  try {
    max_derivative_order_ = std::stoi(order);
    n = static_cast<std::size_t>(std::stoull(size));
  } catch (const std::exception&) {
    throw FmuError("checkpoint '" + path + "' is damaged (bad header)");
  }
  std::string bytes(n, '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(n));
  if (static_cast<std::size_t>(in.gcount()) != n) throw FmuError("checkpoint '" + path + "' is truncated");
  inst_->deserialize_state(bytes);
}

std::string FmuModel::state_attribute() const {
  return md_ && md_->fmi_major == 3 ? "canGetAndSetFMUState" : "canGetAndSetFMUstate";
}

std::string FmuModel::value_text(const std::string& name) {
  const Variable* v = md_ ? md_->find(name) : nullptr;
  if (!v || !inst_) throw FmuError("FMU " + label_ + ": no variable '" + name + "' (or not configured)");
  return inst_->get_text(*v, "(read by name)");
}

void FmuModel::save_snapshot() { inst_->save_state(); }
void FmuModel::restore_snapshot() { inst_->restore_state(); }

double FmuModel::array_element(const Component& c, const std::string& when) {
  const std::vector<double> all = inst_->get_array(*c.var, array_size(*c.var), when);
  if (c.element >= static_cast<long long>(all.size()))
    throw FmuError("FMU " + label_ + ": element " + std::to_string(c.element + 1) + " of '" + c.var->name + "' " + when +
                   " is beyond its " + std::to_string(all.size()) + " values");
  return all[static_cast<std::size_t>(c.element)];
}

double FmuModel::read(const Component& c, const std::string& when) {
  if (!c.var) return c.constant;
  const double x = c.element < 0 ? inst_->get_number(*c.var, when) : array_element(c, when);
  return c.factor == 1 && c.offset == 0 ? x : c.factor * x + c.offset;  // untouched bits without a conversion
}

void FmuModel::write(const Component& c, double value, const PortMap& p, const std::string& when) {
  if (!c.var) return;
  const Variable& v = *c.var;
  Scalar s;
  if (c.factor != 1 || c.offset != 0) value = c.factor * value + c.offset;
  s.number = value;
  if (is_integer(v.type)) {
    const double r = std::nearbyint(value);
    const bool fmi2 = v.type == VarType::Integer || (v.type == VarType::Enumeration && md_->fmi_major == 2);
    long double lo = 0, hi = 0;
    integer_range(v.type == VarType::Enumeration && !fmi2 ? VarType::Int64 : v.type, &lo, &hi);
    // The 64-bit bounds as doubles round up to 2^63 and 2^64, which do not fit: hence < there.
    const bool wide = v.type == VarType::Int64 || v.type == VarType::UInt64 || (v.type == VarType::Enumeration && !fmi2);
    const long double x = static_cast<long double>(r);
    if (!(x >= lo && (wide ? x < hi : x <= hi)))
      throw cosim::InputError("input '" + p.name + "': " + std::to_string(value) + " does not fit FMU " +
                              type_name(v.type) + " variable '" + v.name + "' (" +
                              (fmi2 ? std::string("32-bit") : std::string(type_name(v.type)) + " range") + ")");
    s.number = r;  // the nearest integer
  } else if (v.type == VarType::Boolean) {
    s.number = value > 0.5 ? 1 : 0;
  }
  if (c.element >= 0) {  // an array element: read the array, change one value, set it all
    std::vector<double> all = inst_->get_array(v, array_size(v), when);
    if (c.element >= static_cast<long long>(all.size()))
      throw FmuError("FMU " + label_ + ": input port '" + p.name + "': element " + std::to_string(c.element + 1) + " of '" +
                     v.name + "' is beyond its " + std::to_string(all.size()) + " values");
    all[static_cast<std::size_t>(c.element)] = s.number;
    inst_->set_array(v, all, when);
    return;
  }
  inst_->set(v, s, when);
}

cosim::Kinematics FmuModel::kinematics_of(const std::string& port, const std::string& when) {
  if (auto it = received_.find(port); it != received_.end()) return it->second;
  for (const auto* list : {&outputs_, &inputs_})
    for (const auto& p : *list)
      if (p.name == port) return cosim::Kinematics::from_value(read_output(p, when));
  throw std::logic_error("no kinematics port " + port);
}

Value FmuModel::read_output(const PortMap& p, const std::string& when) {
  switch (p.kind) {
    case SignalKind::Scalar:
      return {read(p.scalar, when)};
    case SignalKind::Kinematics: {
      cosim::Kinematics k;
      for (int i = 0; i < 3; ++i) {
        k.position[i] = read(p.position[i], when);
        k.velocity[i] = read(p.velocity[i], when);
        k.angular_velocity[i] = read(p.angular_velocity[i], when);
      }
      if (p.orientation == OrientationMap::Quaternion) {
        cosim::Quat q;
        for (int i = 0; i < 4; ++i) q[i] = read(p.quaternion[i], when);
        const double n = cosim::quat_norm(q);
        if (!(std::abs(n - 1) < 1e-3))
          throw FmuError("FMU " + label_ + ": output port '" + p.name + "': the quaternion " + when + " has norm " +
                         std::to_string(n) + ", not 1; check the order [w, x, y, z] in " + p.path +
                         ".kinematics.orientation.quaternion");
        // Unit to rounding: as the FMU gives it (the numbers a native participant with the same
        // model sends); else normalized.
        k.orientation = std::abs(n - 1) <= 1e-12 ? q : cosim::quat_normalized(q);
      } else if (p.orientation == OrientationMap::Angles) {
        std::array<double, 3> a{};
        for (int i = 0; i < 3; ++i) a[i] = read(p.angles[i], when);
        k.orientation = quat_from_angles(p.sequence, a);
      }
      if (p.angular_velocity_in_body) k.angular_velocity = rotate(k.orientation, k.angular_velocity);
      return k.to_value();
    }
    case SignalKind::Wrench: {
      cosim::Wrench w;
      for (int i = 0; i < 3; ++i) {
        w.force[i] = read(p.force[i], when);
        w.torque[i] = read(p.torque[i], when);
      }
      if (!p.frame_port.empty()) {
        const cosim::Quat q = kinematics_of(p.frame_port, when).orientation;
        w.force = rotate(q, w.force);
        w.torque = rotate(q, w.torque);
      }
      if (!p.point_port.empty()) {
        w.point = kinematics_of(p.point_port, when).position;
      } else {
        for (int i = 0; i < 3; ++i) w.point[i] = read(p.point[i], when);
      }
      return w.to_value();
    }
  }
  return {};
}

void FmuModel::write_input(const PortMap& p, const Value& v, const std::string& when) {
  switch (p.kind) {
    case SignalKind::Scalar:
      write(p.scalar, v[0], p, when);
      return;
    case SignalKind::Kinematics: {
      const cosim::Kinematics k = cosim::Kinematics::from_value(v);
      received_[p.name] = k;
      for (int i = 0; i < 3; ++i) {
        write(p.position[i], k.position[i], p, when);
        write(p.velocity[i], k.velocity[i], p, when);
      }
      const cosim::Vec3 w = p.angular_velocity_in_body ? rotate_back(k.orientation, k.angular_velocity)
                                                       : k.angular_velocity;
      for (int i = 0; i < 3; ++i) write(p.angular_velocity[i], w[i], p, when);
      if (p.orientation == OrientationMap::Quaternion) {
        const cosim::Quat q = cosim::quat_normalized(k.orientation);
        for (int i = 0; i < 4; ++i) write(p.quaternion[i], q[i], p, when);
      } else if (p.orientation == OrientationMap::Angles) {
        const auto a = angles_from_quat(p.sequence, k.orientation);
        for (int i = 0; i < 3; ++i) write(p.angles[i], a[i], p, when);
      }
      return;
    }
    case SignalKind::Wrench: {
      cosim::Wrench w = cosim::Wrench::from_value(v);
      if (p.point_is_input) {  // the FMU takes the point: the torque as received, about it
        for (int i = 0; i < 3; ++i) write(p.point[i], w.point[i], p, when);
      } else {
        cosim::Vec3 point{};
        if (!p.point_port.empty()) point = kinematics_of(p.point_port, when).position;
        else
          for (int i = 0; i < 3; ++i) point[i] = read(p.point[i], when);
        w = w.shifted_to(point);  // the torque about the point the FMU expects
      }
      if (!p.frame_port.empty()) {
        const cosim::Quat q = kinematics_of(p.frame_port, when).orientation;
        w.force = rotate_back(q, w.force);
        w.torque = rotate_back(q, w.torque);
      }
      for (int i = 0; i < 3; ++i) {
        write(p.force[i], w.force[i], p, when);
        write(p.torque[i], w.torque[i], p, when);
      }
      return;
    }
  }
}

cosim::Signals FmuModel::read_outputs(const std::string& when) {
  cosim::Signals s;
  // Kinematics first: wrench outputs may refer to them (frame, reference point).
  for (const bool kin : {true, false})
    for (const auto& p : outputs_)
      if ((p.kind == SignalKind::Kinematics) == kin) s[p.name] = {p.kind, read_output(p, when)};
  return s;
}

cosim::Signals FmuModel::initial_outputs() { return read_outputs("after initialization"); }

// An FMU with canInterpolateInputs="true" gets the time derivatives of the input polynomial at
// the sub-step's start (fmi2SetRealInputDerivatives, orders 1..3), so it follows the predictor
// within a doStep instead of holding the value (docs/fmi.md, "Input derivatives"). Only
// components that reach a Real variable unconverted: scalars, and a kinematics port's
// position, velocity and (ground-frame) angular velocity, and a quaternion's first derivative.
// Euler angles and wrenches, which are converted before they are set, are held.
void FmuModel::write_input_derivatives(const cosim::StepInputs& in, cosim::TimePoint t, const std::string& when) {
  const double L = cosim::to_seconds(in.length());
  const double s = static_cast<double>(cosim::to_ns(t - in.t_start())) / static_cast<double>(cosim::to_ns(in.length()));
  for (const auto& p : inputs_) {
    if (p.kind == SignalKind::Wrench) continue;
    const cosim::InputPolynomial& poly = in.polynomial(p.name);
    const int n = cosim::tangent_size(p.kind);
    std::vector<std::pair<int, const Component*>> parts;  // tangent index, its variable
    if (p.kind == SignalKind::Scalar) {
      parts.push_back({0, &p.scalar});
    } else {
      for (int i = 0; i < 3; ++i) {
        parts.push_back({cosim::Kinematics::kTangentPosition + i, &p.position[i]});
        parts.push_back({cosim::Kinematics::kTangentVelocity + i, &p.velocity[i]});
        if (!p.angular_velocity_in_body) parts.push_back({cosim::Kinematics::kTangentAngularVelocity + i, &p.angular_velocity[i]});
      }
    }
    // A quaternion's first derivative, by a central difference of the polynomial on the
    // rotation group (relative truncation ~1e-10, rounding ~1e-11): enough for an FMU that
    // extrapolates the pose linearly; higher orders of the orientation are not passed.
    if (p.kind == SignalKind::Kinematics && p.orientation == OrientationMap::Quaternion && poly.n_coefficients > 1) {
      const double ds = 1e-5;
      const cosim::Value a = poly.evaluate(s - ds), b = poly.evaluate(s + ds);
      for (int i = 0; i < 4; ++i)
        if (p.quaternion[i].var && p.quaternion[i].var->type == VarType::Real)
          inst_->set_input_derivative(*p.quaternion[i].var, 1, (b[3 + i] - a[3 + i]) / (2 * ds * L), when);
    } else if (p.kind == SignalKind::Kinematics && p.orientation == OrientationMap::Quaternion &&
               max_derivative_order_ > 0) {
      for (int i = 0; i < 4; ++i)  // a constant pose this step: no rate left from the last
        if (p.quaternion[i].var && p.quaternion[i].var->type == VarType::Real)
          inst_->set_input_derivative(*p.quaternion[i].var, 1, 0.0, when);
    }
    for (const auto& [index, component] : parts) {
      if (!component->var || component->var->type != VarType::Real) continue;
      double Lj = 1;
      // Orders up to the highest ever set: the standard does not say how long an FMU keeps a
      // derivative, so a lower-order polynomial (e.g. the start-up step's constant) sets the
      // orders it lacks to 0 instead of leaving the previous step's in the FMU.
      const int top = std::max(poly.n_coefficients - 1, max_derivative_order_);
      max_derivative_order_ = top;
      for (int j = 1; j <= top; ++j) {
        Lj *= L;
        // d^j/ds^j of sum_i c_i s^i at s, over L^j (0 beyond the polynomial's degree)
        double d = 0, sk = 1;
        for (int i = j; i < poly.n_coefficients; ++i) {
          double falling = 1;
          for (int f = 0; f < j; ++f) falling *= i - f;
          d += poly.coefficients[i * n + index] * falling * sk;
          sk *= s;
        }
        inst_->set_input_derivative(*component->var, j, component->factor * d / Lj, when);
      }
    }
  }
}

cosim::StepResult FmuModel::step(const cosim::StepInputs& in, bool /*want_average*/) {
  const int n = static_cast<int>(in.length() / inner_step_);
  const double h = cosim::to_seconds(inner_step_);
  for (int k = 0; k < n; ++k) {
    const cosim::TimePoint t = in.t_start() + inner_step_ * k;
    char when[64];
    std::snprintf(when, sizeof when, "at t = %.9g s", cosim::to_seconds(t));
    received_.clear();
    // Scalars and kinematics first: wrench inputs may refer to kinematics (frame, point).
    for (const bool wrench : {false, true})
      for (const auto& p : inputs_)
        if ((p.kind == SignalKind::Wrench) == wrench) write_input(p, in.at(p.name, t), when);
    if (input_derivatives_ && md_->can_interpolate_inputs && inst_->can_set_input_derivatives())
      write_input_derivatives(in, t, when);
    if (const std::optional<double> reached = inst_->do_step(cosim::to_seconds(t), h)) {
      // The FMU ended itself: the run ends at the time it reached (whole ns, within the
      // sub-step), with its outputs there.
      cosim::TimePoint at = t + cosim::Duration(static_cast<int64_t>(std::llround((*reached - cosim::to_seconds(t)) * 1e9)));
      at = std::clamp(at, t, t + inner_step_);
      char text[200];
      std::snprintf(text, sizeof text, "at t = %.9g s", cosim::to_seconds(at));
      received_.clear();
      for (const auto& p : inputs_)
        if (p.kind == SignalKind::Kinematics) received_[p.name] = cosim::Kinematics::from_value(in.at(p.name, at));
      cosim::StepResult r;
      r.outputs = read_outputs(text);
      r.ended_at = at;
      std::snprintf(text, sizeof text,
                    md_->fmi_major == 3 ? "fmi3DoStep at t = %.9g s (step %.9g s) set terminateSimulation: the FMU "
                                          "ended the simulation at its last successful time %.9g s"
                                        : "fmi2DoStep at t = %.9g s (step %.9g s) returned fmi2Discard with fmi2Terminated: the FMU "
                                          "ended the simulation at its last successful time %.9g s",
                    cosim::to_seconds(t), h, *reached);
      r.ended_reason = inst_->who() + " ended itself: " + text;
      return r;
    }
  }
  char when[64];
  std::snprintf(when, sizeof when, "at t = %.9g s", cosim::to_seconds(in.t_end()));
  // Outputs that refer to a kinematics input (wrench frame, reference point) see it at t_end.
  received_.clear();
  for (const auto& p : inputs_)
    if (p.kind == SignalKind::Kinematics)
      received_[p.name] = cosim::Kinematics::from_value(in.at(p.name, in.t_end()));
  cosim::StepResult r;
  r.outputs = read_outputs(when);
  // No interval averages: an FMU reports values at communication points only.
  return r;
}

}  // namespace fmu
