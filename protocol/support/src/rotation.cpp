#include "cosim/rotation.hpp"

#include <cmath>

namespace cosim {

Quat quat_multiply(const Quat& a, const Quat& b) {
  return {a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
          a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
          a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
          a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]};
}

Quat quat_conjugate(const Quat& q) { return {q[0], -q[1], -q[2], -q[3]}; }

double quat_norm(const Quat& q) {
  return std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
}

Quat quat_normalized(const Quat& q) {
  const double n = quat_norm(q);
  return {q[0] / n, q[1] / n, q[2] / n, q[3] / n};
}

Quat quat_exp(const Vec3& r) {
  const double angle = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
  const double half = 0.5 * angle;
  // sin(half)/angle, with its Taylor series near zero to keep full precision.
  const double k = angle < 1e-6 ? 0.5 - angle * angle / 48.0 : std::sin(half) / angle;
  return {std::cos(half), k * r[0], k * r[1], k * r[2]};
}

Vec3 quat_log(const Quat& q_in) {
  Quat q = q_in;
  if (q[0] < 0) q = {-q[0], -q[1], -q[2], -q[3]};
  const double s = std::sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const double angle = 2.0 * std::atan2(s, q[0]);
  const double k = s < 1e-12 ? 2.0 / q[0] : angle / s;
  return {k * q[1], k * q[2], k * q[3]};
}

Vec3 quat_relative(const Quat& a, const Quat& b) {
  return quat_log(quat_multiply(quat_conjugate(a), b));
}

Vec3 quat_rotate(const Quat& q, const Vec3& v) {
  const Quat p{0, v[0], v[1], v[2]};
  const Quat r = quat_multiply(quat_multiply(q, p), quat_conjugate(q));
  return {r[1], r[2], r[3]};
}

}  // namespace cosim
