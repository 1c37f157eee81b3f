// A rigid body's pose played from keyframes (time, position, unit quaternion): positions
// piecewise linear or C1 cubic (Catmull-Rom tangents), orientations by slerp with the
// segment's constant angular velocity. Before the first and after the last keyframe the body
// holds still. The same convention as dem_run's tool motion (docs/dem.md), written here again
// because adapters share nothing with the DEM but the bus.
#pragma once

#include <string>
#include <vector>

#include "cosim/rotation.hpp"

namespace prescribed {

struct Keyframe {
  double time = 0;
  cosim::Vec3 position{};
  cosim::Quat orientation{1, 0, 0, 0};
};

struct Pose {
  cosim::Vec3 position{}, velocity{}, angular_velocity{};  // ground frame
  cosim::Quat orientation{1, 0, 0, 0};
};

struct Trajectory {
  enum class Interpolation { linear, cubic } interpolation = Interpolation::linear;
  std::vector<Keyframe> keyframes;  // validated: times strictly increasing, unit quaternions
  Pose evaluate(double t) const;
};

// Normalises the quaternions and checks the times; throws std::invalid_argument naming `what`.
void validate(std::vector<Keyframe>& keys, const std::string& what);
// Rows "time,x,y,z,qw,qx,qy,qz" (one header line allowed); throws std::runtime_error naming
// the file and the line.
std::vector<Keyframe> load_csv(const std::string& path);

}  // namespace prescribed
