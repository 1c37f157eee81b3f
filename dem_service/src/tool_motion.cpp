#include "dem/tool_motion.hpp"

namespace dem {

ToolPose ToolMotion::evaluate(double t) const {
  const cosim::Pose p = cosim::Trajectory::evaluate(t);
  ToolPose out;
  out.position = {p.position[0], p.position[1], p.position[2]};
  out.orientation = {p.orientation[0], p.orientation[1], p.orientation[2], p.orientation[3]};
  out.velocity = {p.velocity[0], p.velocity[1], p.velocity[2]};
  out.angular_velocity = {p.angular_velocity[0], p.angular_velocity[1], p.angular_velocity[2]};
  return out;
}

}  // namespace dem
