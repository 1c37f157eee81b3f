// The engine's boundary to the typed coupling quantities (cosim/quantities.hpp, bus-free).
// Inside the engine a tool's pose (ToolPose) and the soil's wrench on it (dem::Wrench, summed
// in the contact loops) stay in dem::Vec3/Quat, the hot-loop types; they cross to
// cosim::Kinematics and cosim::Wrench here and nowhere else.
#pragma once

#include "cosim/quantities.hpp"
#include "dem/engine.hpp"
#include "dem/state.hpp"

namespace dem {

cosim::Vec3 to_cosim(Vec3 v);
Vec3 from_cosim(const cosim::Vec3& v);

cosim::Kinematics to_kinematics(const ToolPose& pose);
// Takes the quaternion as it is (no normalisation).
ToolPose to_tool_pose(const cosim::Kinematics& k);

// The engine's wrench (torque about the tool's reference point) with that point.
cosim::Wrench to_wrench(const Wrench& w, Vec3 reference_point);

}  // namespace dem
