// A signal of time through keyframes (t_i, v_i), shared by the machine models' YAML programs
// (the wheel loader's maneuver, the hauler's tipping): constant before the first and after the
// last keyframe; between keyframes either linear or "smooth" (cubic smoothstep: C1 with zero
// rate at every keyframe, so each segment is a pulse that starts and ends at rest).
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <string>
#include <vector>

namespace mbs {

struct Profile {
  std::vector<std::array<double, 2>> knots;  // [time s, value], times strictly increasing
  double value(double t, bool smooth) const;
  double rate(double t, bool smooth) const;  // d value / dt
// Machine models are C++17 (Simbody's headers); the comparison is for C++20 code (tests).
#if __cplusplus >= 202002L
  bool operator==(const Profile&) const = default;
#endif
};

// Reads n[key], a non-empty list of [time, value] pairs with finite numbers and strictly
// increasing times. Throws cosim::config::ConfigError naming parent.key (and the entry) and
// the fix.
Profile read_profile(const YAML::Node& n, const std::string& parent, const std::string& key);

}  // namespace mbs
