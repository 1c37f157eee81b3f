#include "cosim/time.hpp"

#include <cmath>
#include <sstream>

#include "cosim/yaml_config.hpp"

namespace cosim {

Duration seconds_to_duration(double seconds, const std::string& what) {
  if (!std::isfinite(seconds) || seconds < 0 || seconds > 9.0e9)
    throw config::ConfigError(what + ": expected a time in seconds between 0 and 9e9, got " +
                              std::to_string(seconds) + " s; give one in that range");
  const double ns = seconds * 1e9;
  const double whole = std::round(ns);
  if (std::abs(ns - whole) > 1e-3) {
    std::ostringstream msg;
    msg.precision(17);
    msg << what << ": " << seconds
        << " s is not a whole number of nanoseconds (simulation time counts whole ns); round it"
           " to whole nanoseconds, e.g. 1e-4 or 2.5e-5";
    throw config::ConfigError(msg.str());
  }
  return Duration(static_cast<std::int64_t>(whole));
}

TimePoint seconds_to_time_point(double seconds, const std::string& what) {
  return TimePoint(seconds_to_duration(seconds, what));
}

}  // namespace cosim
