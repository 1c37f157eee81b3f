#include "dem/tool_motion.hpp"

#include <algorithm>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace dem {
namespace {

// World-frame angular velocity that turns a into b in time h (b = dq * a).
Vec3 angular_velocity(const Quat& a, Quat b, double h) {
  if (a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z < 0) b = {-b.w, -b.x, -b.y, -b.z};
  // dq = b * conj(a)
  const Quat c{a.w, -a.x, -a.y, -a.z};
  const Quat d{b.w * c.w - b.x * c.x - b.y * c.y - b.z * c.z,
               b.w * c.x + b.x * c.w + b.y * c.z - b.z * c.y,
               b.w * c.y - b.x * c.z + b.y * c.w + b.z * c.x,
               b.w * c.z + b.x * c.y - b.y * c.x + b.z * c.w};
  const double s = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
  if (s < 1e-300) return {};
  const double angle = 2 * std::atan2(s, d.w);
  return (angle / (h * s)) * Vec3{d.x, d.y, d.z};
}

}  // namespace

ToolPose ToolMotion::evaluate(double t) const {
  ToolPose p;
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
  // Segment [i, i+1] containing t.
  const auto it = std::upper_bound(k.begin(), k.end(), t,
                                   [](double tt, const Keyframe& f) { return tt < f.time; });
  const std::size_t i = static_cast<std::size_t>(it - k.begin()) - 1;
  const double h = k[i + 1].time - k[i].time;
  const double s = (t - k[i].time) / h;
  const Vec3 p0 = k[i].position, p1 = k[i + 1].position;
  if (interpolation == Interpolation::linear) {
    p.position = (1 - s) * p0 + s * p1;
    p.velocity = (1.0 / h) * (p1 - p0);
  } else {
    // Cubic Hermite with Catmull-Rom tangents (one-sided at the ends): C1 positions.
    auto tangent = [&](std::size_t j) {
      if (j == 0) return (1.0 / (k[1].time - k[0].time)) * (k[1].position - k[0].position);
      if (j + 1 == k.size())
        return (1.0 / (k[j].time - k[j - 1].time)) * (k[j].position - k[j - 1].position);
      return (1.0 / (k[j + 1].time - k[j - 1].time)) * (k[j + 1].position - k[j - 1].position);
    };
    const Vec3 m0 = h * tangent(i), m1 = h * tangent(i + 1);
    const double s2 = s * s, s3 = s2 * s;
    p.position = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 +
                 (s3 - s2) * m1;
    p.velocity = (1.0 / h) * ((6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * m0 +
                              (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * m1);
  }
  p.orientation = slerp(k[i].orientation, k[i + 1].orientation, s);
  p.angular_velocity = angular_velocity(k[i].orientation, k[i + 1].orientation, h);
  return p;
}

void validate_keyframes(std::vector<Keyframe>& keys, const std::string& what) {
  for (std::size_t i = 0; i < keys.size(); ++i) {
    Quat& q = keys[i].orientation;
    const double n2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
    if (!(n2 > 1e-12) || !std::isfinite(n2))
      throw std::invalid_argument(what + ": keyframe " + std::to_string(i) +
                                  " has a zero or non-finite quaternion; give [w, x, y, z] "
                                  "with w = 1 for no rotation");
    q = normalized(q);
    if (i > 0 && !(keys[i].time > keys[i - 1].time))
      throw std::invalid_argument(what + ": keyframe times must increase strictly (keyframe " +
                                  std::to_string(i) + " at t = " +
                                  std::to_string(keys[i].time) + ")");
  }
}

std::vector<Keyframe> load_keyframes_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in)
    throw std::runtime_error("motion file '" + path + "' not found: check tools[].motion.csv");
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
      if (keys.empty() && line_no == 1) continue;  // header line
      throw std::runtime_error(path + ":" + std::to_string(line_no) +
                               ": expected 8 numbers 'time,x,y,z,qw,qx,qy,qz'");
    }
    keys.push_back({v[0], {v[1], v[2], v[3]}, {v[4], v[5], v[6], v[7]}});
  }
  if (keys.empty())
    throw std::runtime_error("motion file '" + path + "' has no rows 'time,x,y,z,qw,qx,qy,qz'");
  validate_keyframes(keys, path);
  return keys;
}

}  // namespace dem
