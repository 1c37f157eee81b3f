// Prescribed tool motion: keyframes of position and orientation, interpolated in time by the
// shared cosim::Trajectory (protocol/support/include/cosim/trajectory.hpp), seen as a dem::ToolPose.
#pragma once

#include "cosim/trajectory.hpp"
#include "dem/state.hpp"

namespace dem {

using cosim::Keyframe;
using cosim::load_keyframes_csv;
using cosim::validate_keyframes;

struct ToolMotion : cosim::Trajectory {
  // Pose and velocities at time t. Positions: piecewise linear or Catmull-Rom cubic;
  // orientation: slerp. Before the first / after the last keyframe the tool holds still.
  ToolPose evaluate(double t) const;
};

}  // namespace dem
