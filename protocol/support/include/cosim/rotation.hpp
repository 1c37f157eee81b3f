// Unit quaternions (w, x, y, z) and the exponential map, for predicting orientations on the
// rotation group instead of component-wise.
#pragma once

#include <array>

namespace cosim {

using Quat = std::array<double, 4>;
using Vec3 = std::array<double, 3>;

Quat quat_multiply(const Quat& a, const Quat& b);
Quat quat_conjugate(const Quat& q);
Quat quat_normalized(const Quat& q);
double quat_norm(const Quat& q);
// exp of a rotation vector (axis * angle) as a unit quaternion.
Quat quat_exp(const Vec3& rotation_vector);
// Rotation vector of a unit quaternion, angle in [0, pi] (the shorter of q and -q).
Vec3 quat_log(const Quat& q);
// Rotation vector r with b = a * exp(r): b relative to a, in a's body frame.
Vec3 quat_relative(const Quat& a, const Quat& b);
Vec3 quat_rotate(const Quat& q, const Vec3& v);

}  // namespace cosim
