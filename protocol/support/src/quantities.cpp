#include "cosim/quantities.hpp"

#include <stdexcept>

namespace cosim {

namespace {

// Value offsets of the kinematics' parts: [p(3), q(4), v(3), w(3)].
constexpr int kPosition = 0, kOrientation = 3, kVelocity = 7, kAngularVelocity = 10;

void require_size(const std::vector<double>& v, int size, const char* what, const char* layout) {
  if (static_cast<int>(v.size()) != size)
    throw std::invalid_argument(std::string(what) + " has " + std::to_string(v.size()) +
                                " numbers, expected " + std::to_string(size) + " " + layout +
                                ": pass a value of that kind, in that order");
}

void put(std::vector<double>& out, int at, const Vec3& x) {
  for (int c = 0; c < 3; ++c) out[at + c] = x[c];
}
Vec3 get3(const std::vector<double>& in, int at) { return {in[at], in[at + 1], in[at + 2]}; }

constexpr const char* kKinematicsLayout = "[px py pz qw qx qy qz vx vy vz wx wy wz]";
constexpr const char* kTangentLayout = "[px py pz rx ry rz vx vy vz wx wy wz]";
constexpr const char* kWrenchLayout = "[fx fy fz tx ty tz rx ry rz]";

}  // namespace

const std::vector<std::string>& Kinematics::component_names() {
  static const std::vector<std::string> names{"px", "py", "pz", "qw", "qx", "qy", "qz",
                                              "vx", "vy", "vz", "wx", "wy", "wz"};
  return names;
}

Vec3 Kinematics::velocity_at(const Vec3& point) const {
  const double rx = point[0] - position[0], ry = point[1] - position[1],
               rz = point[2] - position[2];
  const double wx = angular_velocity[0], wy = angular_velocity[1], wz = angular_velocity[2];
  // Summed left to right, v + (w x r) component by component without grouping the cross
  // product: the master's power residuals have always been computed this way.
  return {velocity[0] + wy * rz - wz * ry, velocity[1] + wz * rx - wx * rz,
          velocity[2] + wx * ry - wy * rx};
}

Value Kinematics::to_value() const {
  Value v(kSize);
  put(v, kPosition, position);
  for (int c = 0; c < 4; ++c) v[kOrientation + c] = orientation[c];
  put(v, kVelocity, velocity);
  put(v, kAngularVelocity, angular_velocity);
  return v;
}

Kinematics Kinematics::from_value(const Value& v) {
  require_size(v, kSize, "kinematics value", kKinematicsLayout);
  Kinematics k;
  k.position = get3(v, kPosition);
  for (int c = 0; c < 4; ++c) k.orientation[c] = v[kOrientation + c];
  k.velocity = get3(v, kVelocity);
  k.angular_velocity = get3(v, kAngularVelocity);
  return k;
}

std::vector<double> Kinematics::to_tangent(const Quat& reference) const {
  std::vector<double> t(kTangentSize);
  put(t, kTangentPosition, position);
  put(t, kTangentRotation, quat_relative(reference, orientation));
  put(t, kTangentVelocity, velocity);
  put(t, kTangentAngularVelocity, angular_velocity);
  return t;
}

Kinematics Kinematics::from_tangent(const std::vector<double>& t, const Quat& reference) {
  require_size(t, kTangentSize, "kinematics tangent", kTangentLayout);
  Kinematics k;
  k.position = get3(t, kTangentPosition);
  k.orientation = quat_normalized(quat_multiply(reference, quat_exp(get3(t, kTangentRotation))));
  k.velocity = get3(t, kTangentVelocity);
  k.angular_velocity = get3(t, kTangentAngularVelocity);
  return k;
}

std::vector<double> Kinematics::difference(const Kinematics& other) const {
  auto minus = [](const Vec3& a, const Vec3& b) -> Vec3 {
    return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
  };
  std::vector<double> d(kTangentSize);
  put(d, kTangentPosition, minus(position, other.position));
  put(d, kTangentRotation, quat_relative(other.orientation, orientation));
  put(d, kTangentVelocity, minus(velocity, other.velocity));
  put(d, kTangentAngularVelocity, minus(angular_velocity, other.angular_velocity));
  return d;
}

const std::vector<std::string>& Wrench::component_names() {
  static const std::vector<std::string> names{"fx", "fy", "fz", "tx", "ty",
                                              "tz", "rx", "ry", "rz"};
  return names;
}

Wrench Wrench::shifted_to(const Vec3& to) const {
  const Vec3 r{point[0] - to[0], point[1] - to[1], point[2] - to[2]};
  // torque + (r x force), the cross product formed first (as Simbody's % does, which the
  // wheel loader used before this function existed).
  return {force,
          {torque[0] + (r[1] * force[2] - r[2] * force[1]),
           torque[1] + (r[2] * force[0] - r[0] * force[2]),
           torque[2] + (r[0] * force[1] - r[1] * force[0])},
          to};
}

double Wrench::power(const Kinematics& motion) const {
  const Vec3 v = motion.velocity_at(point);
  const Vec3& w = motion.angular_velocity;
  // One sum left to right (not f.v + t.w as two dot products): the operation order of the
  // master's power residuals, compared bit for bit.
  return force[0] * v[0] + force[1] * v[1] + force[2] * v[2] + torque[0] * w[0] +
         torque[1] * w[1] + torque[2] * w[2];
}

Value Wrench::to_value() const {
  Value v(kSize);
  put(v, kForce, force);
  put(v, kTorque, torque);
  put(v, kPoint, point);
  return v;
}

Wrench Wrench::from_value(const Value& v) {
  require_size(v, kSize, "wrench value", kWrenchLayout);
  return {get3(v, kForce), get3(v, kTorque), get3(v, kPoint)};
}

}  // namespace cosim
