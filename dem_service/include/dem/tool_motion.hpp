// Prescribed tool motion: keyframes of position and orientation, interpolated in time.
#pragma once

#include <string>
#include <vector>

#include "dem/state.hpp"
#include "dem/vec3.hpp"

namespace dem {

struct Keyframe {
  double time = 0;
  Vec3 position;
  Quat orientation;
};

struct ToolMotion {
  enum class Interpolation { linear, cubic };
  Interpolation interpolation = Interpolation::linear;
  std::vector<Keyframe> keyframes;  // strictly increasing time; empty means fixed at origin

  // Pose and velocities at time t. Positions: piecewise linear or Catmull-Rom cubic;
  // orientation: slerp. Before the first / after the last keyframe the tool holds still.
  ToolPose evaluate(double t) const;
};

// Reads "time,x,y,z,qw,qx,qy,qz" rows (a header line is allowed). Throws std::runtime_error
// naming the file, the line and the fix.
std::vector<Keyframe> load_keyframes_csv(const std::string& path);

// Checks times increase and quaternions are non-zero (normalising them); throws
// std::invalid_argument naming `what`.
void validate_keyframes(std::vector<Keyframe>& keys, const std::string& what);

}  // namespace dem
