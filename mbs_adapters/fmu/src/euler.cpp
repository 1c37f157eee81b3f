#include "euler.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fmu {

EulerSequence parse_sequence(const std::string& text) {
  EulerSequence s;
  s.name = text;
  if (text.size() != 3) throw std::invalid_argument("'" + text + "' is not three axes");
  for (int i = 0; i < 3; ++i) {
    const char c = static_cast<char>(std::tolower(static_cast<unsigned char>(text[i])));
    if (c < 'x' || c > 'z') throw std::invalid_argument("'" + text + "' has an axis other than x, y, z");
    s.axes[i] = c - 'x';
  }
  if (s.axes[0] == s.axes[1] || s.axes[1] == s.axes[2])
    throw std::invalid_argument("'" + text + "' turns about the same axis twice in a row");
  return s;
}

namespace {

cosim::Quat axis_quat(int axis, double angle) {
  cosim::Quat q{std::cos(angle / 2), 0, 0, 0};
  q[1 + axis] = std::sin(angle / 2);
  return q;
}

// Rotation matrix of a unit quaternion (body -> ground), row-major.
std::array<std::array<double, 3>, 3> matrix(const cosim::Quat& q) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return {{{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
           {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
           {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}}};
}

// +1 when (a, b, c) is a cyclic order of (x, y, z).
double parity(int a, int b, int c) {
  return ((a == 0 && b == 1 && c == 2) || (a == 1 && b == 2 && c == 0) || (a == 2 && b == 0 && c == 1)) ? 1.0 : -1.0;
}

}  // namespace

cosim::Quat quat_from_angles(const EulerSequence& s, const std::array<double, 3>& a) {
  cosim::Quat q = axis_quat(s.axes[0], a[0]);
  q = cosim::quat_multiply(q, axis_quat(s.axes[1], a[1]));
  q = cosim::quat_multiply(q, axis_quat(s.axes[2], a[2]));
  return cosim::quat_normalized(q);
}

std::array<double, 3> angles_from_quat(const EulerSequence& s, const cosim::Quat& q) {
  const auto R = matrix(cosim::quat_normalized(q));
  const int a = s.axes[0], b = s.axes[1], c = s.axes[2];
  std::array<double, 3> out{};
  if (a != c) {  // Tait-Bryan: R = R_a R_b R_c, R[a][c] = sign * sin(a1)
    const double sg = parity(a, b, c);
    const double sin1 = std::clamp(sg * R[a][c], -1.0, 1.0);
    out[1] = std::asin(sin1);
    if (std::abs(sin1) < 1 - 1e-12) {
      out[0] = std::atan2(-sg * R[b][c], R[c][c]);
      out[2] = std::atan2(-sg * R[a][b], R[a][a]);
    } else {  // gimbal lock: a2 = 0, a0 from the rotation that is left
      out[2] = 0;
      out[0] = std::atan2(sg * R[c][b], R[b][b]);
    }
  } else {  // proper Euler: R = R_a R_b R_a, R[a][a] = cos(a1)
    const int d = 3 - a - b;
    const double sg = parity(a, b, d);
    const double cos1 = std::clamp(R[a][a], -1.0, 1.0);
    out[1] = std::acos(cos1);
    if (std::abs(cos1) < 1 - 1e-12) {
      out[0] = std::atan2(R[b][a], -sg * R[d][a]);
      out[2] = std::atan2(R[a][b], sg * R[a][d]);
    } else {
      out[2] = 0;  // a1 = 0 or pi: R = R_a(a0) R_b(a1)
      out[0] = std::atan2((cos1 > 0 ? -sg : sg) * R[b][d], R[b][b]);
    }
  }
  return out;
}

}  // namespace fmu
