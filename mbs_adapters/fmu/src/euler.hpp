// Euler and Tait-Bryan angles <-> unit quaternions, for FMUs that carry orientation as three
// angles. A sequence names three body-fixed (intrinsic) rotation axes, e.g. "zyx": rotate about
// z by a0, then about the new y by a1, then about the newest x by a2, so that the rotation
// body -> ground is R = R_z(a0) R_y(a1) R_x(a2). The extrinsic (space-fixed) sequence "xyz" with
// angles (b0, b1, b2) is the same rotation as the intrinsic "zyx" with (b2, b1, b0).
#pragma once

#include <array>
#include <string>

#include "cosim/rotation.hpp"

namespace fmu {

struct EulerSequence {
  std::array<int, 3> axes{2, 1, 0};  // 0 = x, 1 = y, 2 = z
  std::string name = "zyx";
};

// Parses "zyx", "xyz", "zxz", ... (12 valid sequences: no axis twice in a row). Raises
// std::invalid_argument for anything else.
EulerSequence parse_sequence(const std::string& text);
cosim::Quat quat_from_angles(const EulerSequence& s, const std::array<double, 3>& angles);
// The angles of a unit quaternion: middle angle in [-pi/2, pi/2] (Tait-Bryan) or [0, pi]
// (proper Euler), the others in (-pi, pi]. At the singularity (gimbal lock) the first angle
// takes the whole rotation about the then-parallel outer axes.
std::array<double, 3> angles_from_quat(const EulerSequence& s, const cosim::Quat& q);

}  // namespace fmu
