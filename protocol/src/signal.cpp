#include "cosim/signal.hpp"

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
    case SignalKind::Kinematics: return 13;
    case SignalKind::Wrench: return 9;
  }
  return 0;
}

int tangent_size(SignalKind kind) { return kind == SignalKind::Kinematics ? 12 : value_size(kind); }

std::vector<std::string> component_names(SignalKind kind) {
  switch (kind) {
    case SignalKind::Scalar: return {"value"};
    case SignalKind::Kinematics:
      return {"px", "py", "pz", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz"};
    case SignalKind::Wrench: return {"fx", "fy", "fz", "tx", "ty", "tz", "rx", "ry", "rz"};
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
    const double n = std::sqrt(value[3] * value[3] + value[4] * value[4] + value[5] * value[5] +
                               value[6] * value[6]);
    if (std::abs(n - 1.0) > 1e-6)
      throw ProtocolError(what + ": orientation is not a unit quaternion (norm " +
                          std::to_string(n) + "); normalize it before sending");
  }
}

signal_set_t to_message(const Signals& signals) {
  signal_set_t m{};
  for (const auto& [name, s] : signals) {
    const auto& v = s.value;
    switch (s.kind) {
      case SignalKind::Scalar: m.scalars.push_back({name, v.at(0)}); break;
      case SignalKind::Kinematics: {
        named_kinematics_t k{};
        k.name = name;
        for (int i = 0; i < 3; ++i) k.value.position[i] = v.at(i);
        for (int i = 0; i < 4; ++i) k.value.orientation[i] = v.at(3 + i);
        for (int i = 0; i < 3; ++i) k.value.linear_velocity[i] = v.at(7 + i);
        for (int i = 0; i < 3; ++i) k.value.angular_velocity[i] = v.at(10 + i);
        m.kinematics.push_back(k);
        break;
      }
      case SignalKind::Wrench: {
        named_wrench_t w{};
        w.name = name;
        for (int i = 0; i < 3; ++i) w.value.force[i] = v.at(i);
        for (int i = 0; i < 3; ++i) w.value.torque[i] = v.at(3 + i);
        for (int i = 0; i < 3; ++i) w.value.reference_point[i] = v.at(6 + i);
        m.wrenches.push_back(w);
        break;
      }
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
  for (const auto& k : m.kinematics) {
    const auto& x = k.value;
    add(k.name, SignalKind::Kinematics,
        {x.position[0], x.position[1], x.position[2], x.orientation[0], x.orientation[1],
         x.orientation[2], x.orientation[3], x.linear_velocity[0], x.linear_velocity[1],
         x.linear_velocity[2], x.angular_velocity[0], x.angular_velocity[1],
         x.angular_velocity[2]});
  }
  for (const auto& w : m.wrenches) {
    const auto& x = w.value;
    add(w.name, SignalKind::Wrench,
        {x.force[0], x.force[1], x.force[2], x.torque[0], x.torque[1], x.torque[2],
         x.reference_point[0], x.reference_point[1], x.reference_point[2]});
  }
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
