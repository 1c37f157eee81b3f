#include "profile.hpp"

#include <cosim/yaml_config.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace mbs {

namespace {

double smoothstep(double s) { return s * s * (3 - 2 * s); }

// Index of the segment [knots[i], knots[i+1]] holding t, or -1 outside the knots.
int segment(const std::vector<std::array<double, 2>>& k, double t) {
  if (k.size() < 2 || t <= k.front()[0] || t >= k.back()[0]) return -1;
  const auto it = std::upper_bound(k.begin(), k.end(), t,
                                   [](double v, const std::array<double, 2>& a) { return v < a[0]; });
  return static_cast<int>(it - k.begin()) - 1;
}

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

double Profile::value(double t, bool smooth) const {
  if (knots.empty()) return 0;
  const int i = segment(knots, t);
  if (i < 0) return t <= knots.front()[0] ? knots.front()[1] : knots.back()[1];
  const auto& a = knots[i];
  const auto& b = knots[i + 1];
  const double s = (t - a[0]) / (b[0] - a[0]);
  return a[1] + (b[1] - a[1]) * (smooth ? smoothstep(s) : s);
}

double Profile::rate(double t, bool smooth) const {
  const int i = segment(knots, t);
  if (i < 0) return 0;
  const auto& a = knots[i];
  const auto& b = knots[i + 1];
  const double T = b[0] - a[0];
  const double s = (t - a[0]) / T;
  return (b[1] - a[1]) / T * (smooth ? 6 * s * (1 - s) : 1.0);
}

Profile read_profile(const YAML::Node& n, const std::string& parent, const std::string& key) {
  using cosim::config::ConfigError;
  const std::string path = cosim::config::join_path(parent, key);
  const YAML::Node list = n[key];
  if (!list.IsSequence() || list.size() == 0)
    throw ConfigError(path + ": expected a list of [time, value] keyframes, e.g. [[0, 0], [2, 0.1]]");
  Profile p;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YAML::Node k = list[i];
    const std::string kp = path + "." + std::to_string(i);
    if (!k.IsSequence() || k.size() != 2) throw ConfigError(kp + ": expected a [time, value] pair");
    std::array<double, 2> v{};
    for (int j = 0; j < 2; ++j) {
      try {
        v[j] = k[j].as<double>();
      } catch (const YAML::Exception&) {
        throw ConfigError(kp + ": expected numbers, got '" + (k[j].IsScalar() ? k[j].Scalar() : "?") + "'");
      }
      if (!std::isfinite(v[j])) throw ConfigError(kp + ": values must be finite");
    }
    if (!p.knots.empty() && !(v[0] > p.knots.back()[0]))
      throw ConfigError(kp + ": keyframe times must increase strictly (" + num(v[0]) + " after " +
                        num(p.knots.back()[0]) + ")");
    p.knots.push_back(v);
  }
  return p;
}

}  // namespace mbs
