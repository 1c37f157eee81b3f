// What the machine models' parameter files share: the [x, z] and [x, y, z] types, a rigid
// body's mass properties in a planar model, and the readers of their YAML layouts (errors name
// the dotted key, cosim::config::ConfigError).
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <string>
#include <vector>

// Parameters are read by C++17 code too (the Simbody sources); the comparisons are for C++20
// code (tests).
#if __cplusplus >= 202002L
#define MBS_DEFAULT_EQ(T) bool operator==(const T&) const = default;
#else
#define MBS_DEFAULT_EQ(T)
#endif

namespace mbs {

using Vec2 = std::array<double, 2>;  // [x, z] in a planar model's x-z plane
using Vec3 = std::array<double, 3>;

// A rigid body of a planar model; com in the coordinates its model names (a frame at the
// design pose, or the body's own frame).
struct Body {
  double mass = 1;
  Vec2 com{0, 0};
  Vec3 inertia{1, 1, 1};  // principal moments about the centre of mass [kg m2], body axes
  MBS_DEFAULT_EQ(Body)
};

// n[key] as 2 or 3 numbers, or `fallback` when absent.
Vec2 get_vec2(const YAML::Node& n, const std::string& path, const std::string& key, Vec2 fallback);
Vec3 get_vec3(const YAML::Node& n, const std::string& path, const std::string& key, Vec3 fallback);
// Principal moments of inertia (path.inertia): positive, and each at most the sum of the
// other two.
void check_inertia(const Vec3& inertia, const std::string& path);
// root[key] as a Body (keys mass, com if has_com, inertia, and `extra` ones the caller reads);
// keys left out keep `body`'s values. Nothing happens when root has no `key`.
void read_body(const YAML::Node& root, const std::string& parent, const std::string& key, Body& body,
               bool has_com = true, const std::vector<std::string>& extra = {});
// root.limits (max_force [N], max_torque [N m], both > 0): the sanity limits on the wrench the
// soil puts on the coupled body. Keys left out keep the values given.
void read_limits(const YAML::Node& root, const std::string& path, double& max_force, double& max_torque);

}  // namespace mbs
