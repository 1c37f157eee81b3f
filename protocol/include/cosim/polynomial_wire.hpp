// Input polynomials on the wire (polynomial_set_t), for the bus's own code.
#pragma once

#include <cosim/polynomial_set_t.hpp>

#include <string>

#include "cosim/polynomial.hpp"
#include "cosim/signal_wire.hpp"

namespace cosim {

polynomial_set_t to_message(const Polynomials& polynomials);
// Validates sizes, orders (1..4 coefficients), finiteness and unit reference quaternions.
Polynomials from_message(const polynomial_set_t& message, const std::string& what);

}  // namespace cosim
