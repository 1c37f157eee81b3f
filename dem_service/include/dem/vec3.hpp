// Small fixed-size vector and matrix types for the hot loops. Plain structs keep the flat
// arrays in State trivially copyable and let the compiler keep components in registers.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

namespace dem {

struct Vec3 {
  double x = 0, y = 0, z = 0;
};

inline Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 operator-(Vec3 a) { return {-a.x, -a.y, -a.z}; }
inline Vec3 operator*(double s, Vec3 a) { return {s * a.x, s * a.y, s * a.z}; }
inline Vec3 operator*(Vec3 a, double s) { return {s * a.x, s * a.y, s * a.z}; }
inline Vec3& operator+=(Vec3& a, Vec3 b) {
  a.x += b.x;
  a.y += b.y;
  a.z += b.z;
  return a;
}
inline Vec3& operator-=(Vec3& a, Vec3 b) {
  a.x -= b.x;
  a.y -= b.y;
  a.z -= b.z;
  return a;
}
inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double norm2(Vec3 a) { return dot(a, a); }
inline double norm(Vec3 a) { return std::sqrt(dot(a, a)); }

// Any component != 0 (NaN counts as nonzero, -0 as zero), as one integer test: the three
// floating-point compares cost six branches.
inline bool nonzero(Vec3 a) {
  std::uint64_t ix, iy, iz;
  std::memcpy(&ix, &a.x, sizeof ix);
  std::memcpy(&iy, &a.y, sizeof iy);
  std::memcpy(&iz, &a.z, sizeof iz);
  return ((ix | iy | iz) << 1) != 0;
}

// a if pick else b, by bit masks (no branch): for tests that the branch predictor cannot learn
// at the end of a long chain of arithmetic. Exact: the bits of the chosen operand.
inline double select(bool pick, double a, double b) {
  std::uint64_t ia, ib;
  std::memcpy(&ia, &a, sizeof ia);
  std::memcpy(&ib, &b, sizeof ib);
  const std::uint64_t mask = -static_cast<std::uint64_t>(pick);
  const std::uint64_t r = (ia & mask) | (ib & ~mask);
  double out;
  std::memcpy(&out, &r, sizeof out);
  return out;
}
inline Vec3 select(bool pick, Vec3 a, Vec3 b) {
  return {select(pick, a.x, b.x), select(pick, a.y, b.y), select(pick, a.z, b.z)};
}

// Row-major 3x3 rotation matrix.
struct Mat3 {
  double m[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
};
inline Vec3 operator*(const Mat3& R, Vec3 v) {
  return {R.m[0][0] * v.x + R.m[0][1] * v.y + R.m[0][2] * v.z,
          R.m[1][0] * v.x + R.m[1][1] * v.y + R.m[1][2] * v.z,
          R.m[2][0] * v.x + R.m[2][1] * v.y + R.m[2][2] * v.z};
}

// Unit quaternion w + xi + yj + zk.
struct Quat {
  double w = 1, x = 0, y = 0, z = 0;
};
Mat3 to_matrix(const Quat& q);
Quat normalized(const Quat& q);
// Rotation angle (radians, in [0, pi]) of b relative to a.
double angle_between(const Quat& a, const Quat& b);

}  // namespace dem
