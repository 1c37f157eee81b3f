// Typed coupling quantities: the rigid-body kinematics a machine sends and the wrench the soil
// returns. The flat layouts of a signal Value are written here (quantities.cpp) and nowhere else:
//   kinematics [px py pz, qw qx qy qz, vx vy vz, wx wy wz]  13 numbers
//   wrench     [fx fy fz, tx ty tz, rx ry rz]               9 numbers, torque about r
// and so are the tangent coordinates that polynomials and deviations use for kinematics:
//   [px py pz, rx ry rz, vx vy vz, wx wy wz]  12 numbers, r the rotation vector of the
//   orientation relative to a reference orientation (cosim/rotation.hpp's quat_relative).
// Plain C++17 without bus or LCM, so the Simbody model (compiled as C++17) and the DEM engine
// include it; the conversions to the wire types kinematics_t and wrench_t are in signal.hpp.
// The arithmetic keeps the operation order of the formulas it replaced: results are compared
// bit for bit across refactors.
#pragma once

#include <string>
#include <vector>

#include "cosim/rotation.hpp"

namespace cosim {

// A signal's value as it is stored and carried: a scalar [v], or the layouts above.
using Value = std::vector<double>;

struct Kinematics {
  Vec3 position{};               // of the body's reference point, ground frame [m]
  Quat orientation{1, 0, 0, 0};  // unit quaternion (w, x, y, z), body -> ground
  Vec3 velocity{};               // of the reference point, ground frame [m/s]
  Vec3 angular_velocity{};       // ground frame [rad/s]

  static constexpr int kSize = 13;         // numbers in a Value
  static constexpr int kTangentSize = 12;  // numbers in tangent coordinates
  // Where each 3-vector starts in tangent coordinates (polynomial coefficient rows).
  static constexpr int kTangentPosition = 0, kTangentRotation = 3, kTangentVelocity = 6,
                       kTangentAngularVelocity = 9;
  // "px", "py", ... in Value order, for CSV headers and HDF5 attributes.
  static const std::vector<std::string>& component_names();

  // Velocity of the body-fixed point that is at `point` now: v + w x (point - position).
  Vec3 velocity_at(const Vec3& point) const;

  Value to_value() const;
  // Takes the quaternion as it is (no normalisation). Raises std::invalid_argument unless
  // `value` has 13 numbers.
  static Kinematics from_value(const Value& value);

  // Tangent coordinates with the orientation as its rotation vector relative to `reference`.
  std::vector<double> to_tangent(const Quat& reference) const;
  // Back from tangent coordinates: orientation = normalized(reference * exp(r)). Raises
  // std::invalid_argument unless `tangent` has 12 numbers.
  static Kinematics from_tangent(const std::vector<double>& tangent, const Quat& reference);
  // This minus `other` in tangent coordinates: differences of position and velocities, and the
  // rotation vector of this orientation relative to other's (how far a prediction was off).
  std::vector<double> difference(const Kinematics& other) const;
};

// A force and a torque about a reference point, all in the ground frame.
struct Wrench {
  Vec3 force{};   // [N]
  Vec3 torque{};  // about `point` [N m]
  Vec3 point{};   // reference point [m]

  static constexpr int kSize = 9;  // numbers in a Value
  // Where each 3-vector starts in a Value (polynomial coefficient rows).
  static constexpr int kForce = 0, kTorque = 3, kPoint = 6;
  // "fx", "fy", ... in Value order.
  static const std::vector<std::string>& component_names();

  // The same force system with its torque about `to`: torque + (point - to) x force.
  Wrench shifted_to(const Vec3& to) const;
  // Power of this wrench on a body moving with `motion`: force . (velocity of the body point at
  // `point`) + torque . angular velocity. The same for every shifted_to of the wrench.
  double power(const Kinematics& motion) const;

  Value to_value() const;
  // Raises std::invalid_argument unless `value` has 9 numbers.
  static Wrench from_value(const Value& value);
};

}  // namespace cosim
