#include "dem/coupling.hpp"

namespace dem {

cosim::Vec3 to_cosim(Vec3 v) { return {v.x, v.y, v.z}; }
Vec3 from_cosim(const cosim::Vec3& v) { return {v[0], v[1], v[2]}; }

cosim::Kinematics to_kinematics(const ToolPose& p) {
  const Quat& q = p.orientation;
  return {to_cosim(p.position), {q.w, q.x, q.y, q.z}, to_cosim(p.velocity),
          to_cosim(p.angular_velocity)};
}

ToolPose to_tool_pose(const cosim::Kinematics& k) {
  const cosim::Quat& q = k.orientation;
  return {from_cosim(k.position), {q[0], q[1], q[2], q[3]}, from_cosim(k.velocity),
          from_cosim(k.angular_velocity)};
}

cosim::Wrench to_wrench(const Wrench& w, Vec3 reference_point) {
  return {to_cosim(w.force), to_cosim(w.torque), to_cosim(reference_point)};
}

}  // namespace dem
