#include "cosim/signal_wire.hpp"

#include <cmath>
#include <set>

namespace cosim {

std::string_view kind_name(SignalKind kind) {
  switch (kind) {
    case SignalKind::Scalar: return "scalar";
    case SignalKind::Kinematics: return "kinematics";
    case SignalKind::Wrench: return "wrench";
  }
  return "unknown";
}

SignalKind kind_from_wire(std::int8_t kind, const std::string& what) {
  if (kind == port_t::SCALAR || kind == port_t::KINEMATICS || kind == port_t::WRENCH)
    return static_cast<SignalKind>(kind);
  throw ProtocolError(what + ": unknown signal kind " + std::to_string(kind) +
                      " (allowed: 1 scalar, 2 kinematics, 3 wrench)");
}

int value_size(SignalKind kind) {
  switch (kind) {
    case SignalKind::Scalar: return 1;
    case SignalKind::Kinematics: return Kinematics::kSize;
    case SignalKind::Wrench: return Wrench::kSize;
  }
  return 0;
}

int tangent_size(SignalKind kind) {
  return kind == SignalKind::Kinematics ? Kinematics::kTangentSize : value_size(kind);
}

std::vector<std::string> component_names(SignalKind kind) {
  switch (kind) {
    case SignalKind::Scalar: return {"value"};
    case SignalKind::Kinematics: return Kinematics::component_names();
    case SignalKind::Wrench: return Wrench::component_names();
  }
  return {};
}

bool valid_name(std::string_view name) {
  if (name.empty() || name.size() > 32) return false;
  for (char c : name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  return true;
}

void require_valid_name(std::string_view name, const std::string& what) {
  if (!valid_name(name))
    throw ProtocolError(what + ": '" + std::string(name) +
                        "' is not a valid name (1 to 32 characters of A-Z, a-z, 0-9, _)");
}

void validate_value(SignalKind kind, const Value& value, const std::string& what) {
  if (static_cast<int>(value.size()) != value_size(kind))
    throw ProtocolError(what + ": " + std::string(kind_name(kind)) + " value has " +
                        std::to_string(value.size()) + " components, expected " +
                        std::to_string(value_size(kind)));
  for (std::size_t i = 0; i < value.size(); ++i)
    if (!std::isfinite(value[i]))
      throw ProtocolError(what + ": component " + component_names(kind)[i] +
                          " is not finite (NaN or infinity)");
  if (kind == SignalKind::Kinematics) {
    const double n = quat_norm(Kinematics::from_value(value).orientation);
    if (std::abs(n - 1.0) > 1e-6)
      throw ProtocolError(what + ": orientation is not a unit quaternion (norm " +
                          std::to_string(n) + "); normalize it before sending");
  }
}

namespace {
// Copies n numbers into one of LCM's fixed arrays.
template <class To, class From>
void copy(To& to, const From& from, int n) {
  for (int i = 0; i < n; ++i) to[i] = from[i];
}
Vec3 vec3(const double (&a)[3]) { return {a[0], a[1], a[2]}; }
}  // namespace

kinematics_t to_wire(const Kinematics& k) {
  kinematics_t m{};
  copy(m.position, k.position, 3);
  copy(m.orientation, k.orientation, 4);
  copy(m.linear_velocity, k.velocity, 3);
  copy(m.angular_velocity, k.angular_velocity, 3);
  return m;
}

Kinematics from_wire(const kinematics_t& m) {
  const auto& q = m.orientation;
  return {vec3(m.position), {q[0], q[1], q[2], q[3]}, vec3(m.linear_velocity),
          vec3(m.angular_velocity)};
}

wrench_t to_wire(const Wrench& w) {
  wrench_t m{};
  copy(m.force, w.force, 3);
  copy(m.torque, w.torque, 3);
  copy(m.reference_point, w.point, 3);
  return m;
}

Wrench from_wire(const wrench_t& m) {
  return {vec3(m.force), vec3(m.torque), vec3(m.reference_point)};
}

signal_set_t to_message(const Signals& signals) {
  signal_set_t m{};
  for (const auto& [name, s] : signals) {
    switch (s.kind) {
      case SignalKind::Scalar: m.scalars.push_back({name, s.value.at(0)}); break;
      case SignalKind::Kinematics:
        m.kinematics.push_back({name, to_wire(Kinematics::from_value(s.value))});
        break;
      case SignalKind::Wrench:
        m.wrenches.push_back({name, to_wire(Wrench::from_value(s.value))});
        break;
    }
  }
  set_counts(m);
  return m;
}

Signals from_message(const signal_set_t& m, const std::string& what) {
  Signals out;
  auto add = [&](const std::string& name, SignalKind kind, Value v) {
    const std::string where = what + " signal '" + name + "'";
    require_valid_name(name, where);
    if (out.count(name)) throw ProtocolError(where + ": appears twice");
    validate_value(kind, v, where);
    out[name] = Signal{kind, std::move(v)};
  };
  for (const auto& s : m.scalars) add(s.name, SignalKind::Scalar, {s.value});
  for (const auto& k : m.kinematics)
    add(k.name, SignalKind::Kinematics, from_wire(k.value).to_value());
  for (const auto& w : m.wrenches) add(w.name, SignalKind::Wrench, from_wire(w.value).to_value());
  return out;
}

void check_against_ports(const Signals& signals, const Ports& ports, const std::string& what) {
  std::string declared;
  for (const auto& p : ports) declared += (declared.empty() ? "" : ", ") + p.name;
  // Unknown names first: a misspelt or unknown tool explains the missing one too.
  for (const auto& [name, s] : signals) {
    bool known = false;
    for (const auto& p : ports) known = known || p.name == name;
    if (!known)
      throw ProtocolError(what + ": '" + name + "' is not declared (declared: " + declared + ")");
  }
  for (const auto& p : ports) {
    auto it = signals.find(p.name);
    if (it == signals.end()) throw ProtocolError(what + ": '" + p.name + "' is missing");
    if (it->second.kind != p.kind)
      throw ProtocolError(what + ": '" + p.name + "' is " +
                          std::string(kind_name(it->second.kind)) + ", declared " +
                          std::string(kind_name(p.kind)));
  }
}

std::vector<port_t> to_message(const Ports& ports) {
  std::vector<port_t> out;
  for (const auto& p : ports) out.push_back(port_t{p.name, static_cast<int8_t>(p.kind)});
  return out;
}

Ports ports_from_message(const std::vector<port_t>& ports, const std::string& what) {
  Ports out;
  std::set<std::string> seen;
  for (const auto& p : ports) {
    require_valid_name(p.name, what);
    if (!seen.insert(p.name).second) throw ProtocolError(what + ": '" + p.name + "' declared twice");
    out.push_back({p.name, kind_from_wire(p.kind, what + " '" + p.name + "'")});
  }
  return out;
}

}  // namespace cosim
