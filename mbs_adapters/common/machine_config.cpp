#include "machine_config.hpp"

#include <cosim/yaml_config.hpp>

namespace mbs {

namespace cfg = cosim::config;

Vec2 get_vec2(const YAML::Node& n, const std::string& path, const std::string& key, Vec2 fallback) {
  if (!n[key]) return fallback;
  const auto v = cfg::get_vector(n, path, key, 2);
  return {v[0], v[1]};
}

Vec3 get_vec3(const YAML::Node& n, const std::string& path, const std::string& key, Vec3 fallback) {
  if (!n[key]) return fallback;
  const auto v = cfg::get_vector(n, path, key, 3);
  return {v[0], v[1], v[2]};
}

void check_inertia(const Vec3& I, const std::string& path) {
  for (double v : I)
    if (!(v > 0)) throw cfg::ConfigError(cfg::join_path(path, "inertia") + ": moments must be > 0 [kg m2]");
  if (I[0] + I[1] < I[2] || I[1] + I[2] < I[0] || I[0] + I[2] < I[1])
    throw cfg::ConfigError(cfg::join_path(path, "inertia") +
                           ": principal moments must satisfy the triangle inequality "
                           "(each at most the sum of the other two)");
}

void read_body(const YAML::Node& root, const std::string& parent, const std::string& key, Body& body,
               bool has_com, const std::vector<std::string>& extra) {
  if (!root[key]) return;
  const YAML::Node n = root[key];
  const std::string path = cfg::join_path(parent, key);
  std::vector<std::string> allowed{"mass", "inertia"};
  if (has_com) allowed.push_back("com");
  allowed.insert(allowed.end(), extra.begin(), extra.end());
  cfg::check_keys(n, path, allowed);
  body.mass = cfg::get_positive_or(n, path, "mass", body.mass);
  if (has_com) body.com = get_vec2(n, path, "com", body.com);
  body.inertia = get_vec3(n, path, "inertia", body.inertia);
  check_inertia(body.inertia, path);
}

void read_limits(const YAML::Node& root, const std::string& path, double& max_force, double& max_torque) {
  if (!root["limits"]) return;
  const auto n = root["limits"];
  const auto lp = cfg::join_path(path, "limits");
  cfg::check_keys(n, lp, {"max_force", "max_torque"});
  max_force = cfg::get_positive_or(n, lp, "max_force", max_force);
  max_torque = cfg::get_positive_or(n, lp, "max_torque", max_torque);
}

}  // namespace mbs
