#include "trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace prescribed {
namespace {

using cosim::Quat;
using cosim::Vec3;

Vec3 lerp(const Vec3& a, const Vec3& b, double s) {
  return {(1 - s) * a[0] + s * b[0], (1 - s) * a[1] + s * b[1], (1 - s) * a[2] + s * b[2]};
}

// Shorter-arc rotation from a to b as a world-frame rotation vector (b = exp(w) * a).
Vec3 world_rotation(const Quat& a, const Quat& b) {
  Quat bb = b;
  if (a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] < 0) bb = {-b[0], -b[1], -b[2], -b[3]};
  return cosim::quat_log(cosim::quat_multiply(bb, cosim::quat_conjugate(a)));
}

}  // namespace

Pose Trajectory::evaluate(double t) const {
  Pose p;
  const auto& k = keyframes;
  if (k.empty()) return p;
  if (k.size() == 1 || t <= k.front().time) {
    p.position = k.front().position;
    p.orientation = k.front().orientation;
    return p;
  }
  if (t >= k.back().time) {
    p.position = k.back().position;
    p.orientation = k.back().orientation;
    return p;
  }
  const auto it = std::upper_bound(k.begin(), k.end(), t,
                                   [](double tt, const Keyframe& f) { return tt < f.time; });
  const std::size_t i = static_cast<std::size_t>(it - k.begin()) - 1;
  const double h = k[i + 1].time - k[i].time;
  const double s = (t - k[i].time) / h;
  const Vec3& p0 = k[i].position;
  const Vec3& p1 = k[i + 1].position;
  if (interpolation == Interpolation::linear) {
    p.position = lerp(p0, p1, s);
    for (int c = 0; c < 3; ++c) p.velocity[c] = (p1[c] - p0[c]) / h;
  } else {
    auto tangent = [&](std::size_t j, int c) {  // dx/dt at keyframe j
      if (j == 0) return (k[1].position[c] - k[0].position[c]) / (k[1].time - k[0].time);
      if (j + 1 == k.size())
        return (k[j].position[c] - k[j - 1].position[c]) / (k[j].time - k[j - 1].time);
      return (k[j + 1].position[c] - k[j - 1].position[c]) / (k[j + 1].time - k[j - 1].time);
    };
    const double s2 = s * s, s3 = s2 * s;
    for (int c = 0; c < 3; ++c) {
      const double m0 = h * tangent(i, c), m1 = h * tangent(i + 1, c);
      p.position[c] = (2 * s3 - 3 * s2 + 1) * p0[c] + (s3 - 2 * s2 + s) * m0 +
                      (-2 * s3 + 3 * s2) * p1[c] + (s3 - s2) * m1;
      p.velocity[c] = ((6 * s2 - 6 * s) * p0[c] + (3 * s2 - 4 * s + 1) * m0 +
                       (-6 * s2 + 6 * s) * p1[c] + (3 * s2 - 2 * s) * m1) / h;
    }
  }
  // Slerp as exp(s w) * q0: constant angular velocity w / h over the segment.
  const Vec3 w = world_rotation(k[i].orientation, k[i + 1].orientation);
  p.orientation = cosim::quat_normalized(
      cosim::quat_multiply(cosim::quat_exp({s * w[0], s * w[1], s * w[2]}), k[i].orientation));
  p.angular_velocity = {w[0] / h, w[1] / h, w[2] / h};
  return p;
}

void validate(std::vector<Keyframe>& keys, const std::string& what) {
  if (keys.empty()) throw std::invalid_argument(what + ": no keyframes; give at least one");
  for (std::size_t i = 0; i < keys.size(); ++i) {
    Keyframe& f = keys[i];
    for (double v : f.position)
      if (!std::isfinite(v))
        throw std::invalid_argument(what + ": keyframe " + std::to_string(i) + " has a non-finite position");
    const double n = cosim::quat_norm(f.orientation);
    if (!(n > 1e-6) || !std::isfinite(n))
      throw std::invalid_argument(what + ": keyframe " + std::to_string(i) +
                                  " has a zero or non-finite quaternion; give [w, x, y, z] with "
                                  "w = 1 for no rotation");
    f.orientation = cosim::quat_normalized(f.orientation);
    if (!std::isfinite(f.time) || (i > 0 && !(f.time > keys[i - 1].time)))
      throw std::invalid_argument(what + ": keyframe times must increase strictly (keyframe " +
                                  std::to_string(i) + " at t = " + std::to_string(f.time) + ")");
  }
}

std::vector<Keyframe> load_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("trajectory file '" + path + "' not found");
  std::vector<Keyframe> keys;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ss(line);
    double v[8];
    int n = 0;
    while (n < 8 && ss >> v[n]) ++n;
    if (n != 8) {
      if (keys.empty() && line_no == 1) continue;  // header
      throw std::runtime_error(path + ":" + std::to_string(line_no) +
                               ": expected 8 numbers 'time,x,y,z,qw,qx,qy,qz'");
    }
    keys.push_back({v[0], {v[1], v[2], v[3]}, {v[4], v[5], v[6], v[7]}});
  }
  validate(keys, path);
  return keys;
}

}  // namespace prescribed
