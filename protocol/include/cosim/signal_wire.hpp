// Signals on the wire: the conversions between cosim::Signals, Ports and the typed quantities
// (signal.hpp, quantities.hpp) and the LCM messages that carry them. For the bus's own code
// (links, the participant core, the master, the recorder), not for models.
#pragma once

#include <cosim/kinematics_t.hpp>
#include <cosim/named_scalar_t.hpp>
#include <cosim/port_t.hpp>
#include <cosim/signal_set_t.hpp>
#include <cosim/wrench_t.hpp>

#include <cstdint>
#include <string>
#include <vector>

#include "cosim/signal.hpp"

namespace cosim {

static_assert(static_cast<std::int8_t>(SignalKind::Scalar) == port_t::SCALAR &&
                  static_cast<std::int8_t>(SignalKind::Kinematics) == port_t::KINEMATICS &&
                  static_cast<std::int8_t>(SignalKind::Wrench) == port_t::WRENCH,
              "SignalKind's values are the wire's port_t kinds");

// Raises ProtocolError for a kind byte that is not one of the three.
SignalKind kind_from_wire(std::int8_t kind, const std::string& what);

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
