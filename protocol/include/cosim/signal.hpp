// Signals a participant reads and writes: a kind, a name and a flat value. A scalar's value is
// [v]; kinematics and wrench values have the layouts of cosim::Kinematics and cosim::Wrench
// (quantities.hpp), which convert them to typed form here and to the wire types below.
#pragma once

#include <cosim/kinematics_t.hpp>
#include <cosim/named_scalar_t.hpp>
#include <cosim/port_t.hpp>
#include <cosim/signal_set_t.hpp>
#include <cosim/wrench_t.hpp>

#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "cosim/quantities.hpp"

namespace cosim {

// A received message broke the protocol (bad size, NaN, unknown name...). The text says what.
struct ProtocolError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

enum class SignalKind : std::int8_t {
  Scalar = port_t::SCALAR,
  Kinematics = port_t::KINEMATICS,
  Wrench = port_t::WRENCH,
};

std::string_view kind_name(SignalKind kind);
// Raises ProtocolError for a kind byte that is not one of the three.
SignalKind kind_from_wire(std::int8_t kind, const std::string& what);
int value_size(SignalKind kind);    // 1, 13, 9
int tangent_size(SignalKind kind);  // 1, 12, 9: orientation as a rotation vector
// Component names for CSV headers and HDF5 attributes.
std::vector<std::string> component_names(SignalKind kind);

struct Signal {
  SignalKind kind = SignalKind::Scalar;
  Value value;
};
using Signals = std::map<std::string, Signal>;

struct PortSpec {
  std::string name;
  SignalKind kind = SignalKind::Scalar;
};
using Ports = std::vector<PortSpec>;

// Names of signals and participants: 1..32 characters of [A-Za-z0-9_].
bool valid_name(std::string_view name);
void require_valid_name(std::string_view name, const std::string& what);

// Raises ProtocolError unless value is finite, of the kind's size, and (kinematics) has a unit
// quaternion to within 1e-6.
void validate_value(SignalKind kind, const Value& value, const std::string& what);

// LCM encodes arrays by their count fields: sets them from the vectors (a mismatch would read
// out of bounds). For signal_set_t and polynomial_set_t alike.
template <class Set>
void set_counts(Set& m) {
  m.n_scalars = static_cast<int32_t>(m.scalars.size());
  m.n_kinematics = static_cast<int32_t>(m.kinematics.size());
  m.n_wrenches = static_cast<int32_t>(m.wrenches.size());
}

// The typed quantities on the wire.
kinematics_t to_wire(const Kinematics& k);
Kinematics from_wire(const kinematics_t& k);
wrench_t to_wire(const Wrench& w);
Wrench from_wire(const wrench_t& w);

signal_set_t to_message(const Signals& signals);
// Validates every entry (names, duplicates, finiteness, unit quaternions).
Signals from_message(const signal_set_t& message, const std::string& what);
// Checks that `signals` holds exactly the `ports` (names and kinds).
void check_against_ports(const Signals& signals, const Ports& ports, const std::string& what);

std::vector<port_t> to_message(const Ports& ports);
Ports ports_from_message(const std::vector<port_t>& ports, const std::string& what);

}  // namespace cosim
