// Signals a participant reads and writes: a kind, a name and a flat value. A scalar's value is
// [v]; kinematics and wrench values have the layouts of cosim::Kinematics and cosim::Wrench
// (quantities.hpp), which convert them to typed form. No wire type here: what a model sees
// (participant.hpp) stays free of LCM; signal_wire.hpp converts to and from the messages.
#pragma once

#include <cstdint>
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

// The values are the wire's (port_t::SCALAR, KINEMATICS, WRENCH; checked in signal_wire.hpp).
enum class SignalKind : std::int8_t {
  Scalar = 1,
  Kinematics = 2,
  Wrench = 3,
};

std::string_view kind_name(SignalKind kind);
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

}  // namespace cosim
