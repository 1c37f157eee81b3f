// Simulation time in integer nanoseconds, as two types that cannot be mixed up (libcosim's
// time.hpp is the model): a Duration is a length of time (a macro step, an inner step, an output
// interval), a TimePoint an instant on the simulation clock (a step's start, the run's end).
//   TimePoint - TimePoint = Duration      TimePoint +- Duration = TimePoint
//   Duration * integer = Duration         Duration / Duration = integer, Duration % Duration
// and comparisons within each type. Seconds appear only at the edges: configs are parsed with
// seconds_to_duration / seconds_to_time_point, HDF5, CSV and charts get to_seconds, and messages
// on the wire carry int64 nanoseconds (to_ns, and nanoseconds / time_point_ns back).
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace cosim {

// The simulation's clock: its zero is the co-simulation's time zero, not a wall clock, so it
// has no now().
struct SimulationClock {
  using rep = std::int64_t;
  using period = std::nano;
  using duration = std::chrono::duration<rep, period>;
  using time_point = std::chrono::time_point<SimulationClock>;
  static constexpr bool is_steady = true;
};

using Duration = SimulationClock::duration;
using TimePoint = SimulationClock::time_point;

constexpr Duration nanoseconds(std::int64_t ns) { return Duration(ns); }
constexpr TimePoint time_point_ns(std::int64_t ns) { return TimePoint(Duration(ns)); }
constexpr std::int64_t to_ns(Duration d) { return d.count(); }
constexpr std::int64_t to_ns(TimePoint t) { return t.time_since_epoch().count(); }

// Converts seconds from a config; raises config::ConfigError naming `what` unless the value is
// finite, not negative and a whole number of nanoseconds (to within 1e-3 ns of rounding).
Duration seconds_to_duration(double seconds, const std::string& what);
TimePoint seconds_to_time_point(double seconds, const std::string& what);
inline double to_seconds(Duration d) { return static_cast<double>(d.count()) * 1e-9; }
inline double to_seconds(TimePoint t) { return to_seconds(t.time_since_epoch()); }

}  // namespace cosim
