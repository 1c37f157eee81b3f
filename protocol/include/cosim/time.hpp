// Simulation time is an integer count of nanoseconds wherever it is stored or compared.
#pragma once

#include <cstdint>
#include <string>

namespace cosim {

using Ticks = std::int64_t;  // nanoseconds
constexpr Ticks kTicksPerSecond = 1'000'000'000;

// Converts seconds to ticks; raises config::ConfigError naming `what` unless the value is
// finite, not negative and a whole number of nanoseconds (to within 1e-3 ns of rounding).
Ticks seconds_to_ticks(double seconds, const std::string& what);
inline double to_seconds(Ticks t) { return static_cast<double>(t) * 1e-9; }

}  // namespace cosim
