#include "cosim/time.hpp"

#include <cmath>
#include <sstream>

#include "cosim/yaml_config.hpp"

namespace cosim {

Ticks seconds_to_ticks(double seconds, const std::string& what) {
  if (!std::isfinite(seconds) || seconds < 0 || seconds > 9.0e9)
    throw config::ConfigError(what + ": expected a time in seconds between 0 and 9e9, got " +
                              std::to_string(seconds));
  const double ns = seconds * 1e9;
  const double whole = std::round(ns);
  if (std::abs(ns - whole) > 1e-3) {
    std::ostringstream msg;
    msg.precision(17);
    msg << what << ": " << seconds << " s is not a whole number of nanoseconds";
    throw config::ConfigError(msg.str());
  }
  return static_cast<Ticks>(whole);
}

}  // namespace cosim
