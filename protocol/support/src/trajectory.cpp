#include "cosim/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "cosim/paths.hpp"
#include "cosim/yaml_config.hpp"

namespace cosim {
namespace {

Vec3 scaled(double a, const Vec3& v) { return {a * v[0], a * v[1], a * v[2]}; }
Vec3 difference(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const Quat& a, const Quat& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
}

// Spherical linear interpolation from a to b along the shorter arc, s in [0, 1].
Quat slerp(const Quat& a, Quat b, double s) {
  double c = dot(a, b);
  if (c < 0) {  // q and -q are the same rotation: take the shorter arc
    b = {-b[0], -b[1], -b[2], -b[3]};
    c = -c;
  }
  double wa, wb;
  if (c > 0.9999995) {  // nearly parallel: a linear blend avoids dividing by sin(0)
    wa = 1 - s;
    wb = s;
  } else {
    const double th = std::acos(std::min(c, 1.0));
    const double sn = std::sin(th);
    wa = std::sin((1 - s) * th) / sn;
    wb = std::sin(s * th) / sn;
  }
  return quat_normalized(
      {wa * a[0] + wb * b[0], wa * a[1] + wb * b[1], wa * a[2] + wb * b[2], wa * a[3] + wb * b[3]});
}

// World-frame angular velocity that turns a into b in time h (b = dq * a, shorter arc).
Vec3 angular_velocity(const Quat& a, Quat b, double h) {
  if (dot(a, b) < 0) b = {-b[0], -b[1], -b[2], -b[3]};
  const Quat d = quat_multiply(b, quat_conjugate(a));
  const double s = std::sqrt(d[1] * d[1] + d[2] * d[2] + d[3] * d[3]);
  if (s < 1e-300) return {};
  const double angle = 2 * std::atan2(s, d[0]);
  return scaled(angle / (h * s), {d[1], d[2], d[3]});
}

// `path` and its element i, in the caller's index style.
std::string element(const std::string& path, std::size_t i) {
  const std::string n = std::to_string(i);
  return path.find(']') != std::string::npos ? path + "[" + n + "]" : path + "." + n;
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
  // Segment [i, i+1] containing t.
  const auto it = std::upper_bound(k.begin(), k.end(), t,
                                   [](double tt, const Keyframe& f) { return tt < f.time; });
  const std::size_t i = static_cast<std::size_t>(it - k.begin()) - 1;
  const double h = k[i + 1].time - k[i].time;
  const double s = (t - k[i].time) / h;
  const Vec3& p0 = k[i].position;
  const Vec3& p1 = k[i + 1].position;
  if (interpolation == Interpolation::linear) {
    for (int c = 0; c < 3; ++c) {
      p.position[c] = (1 - s) * p0[c] + s * p1[c];
      p.velocity[c] = (1.0 / h) * (p1[c] - p0[c]);
    }
  } else {
    // Cubic Hermite with Catmull-Rom tangents dx/dt (one-sided at the ends): C1 positions.
    auto tangent = [&](std::size_t j) {
      if (j == 0) return scaled(1.0 / (k[1].time - k[0].time), difference(k[1].position, k[0].position));
      if (j + 1 == k.size())
        return scaled(1.0 / (k[j].time - k[j - 1].time), difference(k[j].position, k[j - 1].position));
      return scaled(1.0 / (k[j + 1].time - k[j - 1].time),
                    difference(k[j + 1].position, k[j - 1].position));
    };
    const Vec3 m0 = scaled(h, tangent(i)), m1 = scaled(h, tangent(i + 1));
    const double s2 = s * s, s3 = s2 * s;
    for (int c = 0; c < 3; ++c) {
      p.position[c] = (2 * s3 - 3 * s2 + 1) * p0[c] + (s3 - 2 * s2 + s) * m0[c] +
                      (-2 * s3 + 3 * s2) * p1[c] + (s3 - s2) * m1[c];
      p.velocity[c] = (1.0 / h) * ((6 * s2 - 6 * s) * p0[c] + (3 * s2 - 4 * s + 1) * m0[c] +
                                   (-6 * s2 + 6 * s) * p1[c] + (3 * s2 - 2 * s) * m1[c]);
    }
  }
  p.orientation = slerp(k[i].orientation, k[i + 1].orientation, s);
  p.angular_velocity = angular_velocity(k[i].orientation, k[i + 1].orientation, h);
  return p;
}

void validate_keyframes(std::vector<Keyframe>& keys, const std::string& what) {
  if (keys.empty())
    throw std::invalid_argument(what + ": no keyframes; give at least one {time, position}");
  for (std::size_t i = 0; i < keys.size(); ++i) {
    Keyframe& f = keys[i];
    const std::string which = what + ": keyframe " + std::to_string(i);
    for (double v : f.position)
      if (!std::isfinite(v))
        throw std::invalid_argument(which + " has a non-finite position; give three numbers in m");
    Quat& q = f.orientation;
    const double n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if (!(n2 > 1e-12) || !std::isfinite(n2))
      throw std::invalid_argument(which + " has a zero or non-finite quaternion; give [w, x, y, z] "
                                          "with w = 1 for no rotation");
    q = quat_normalized(q);
    if (!std::isfinite(f.time) || (i > 0 && !(f.time > keys[i - 1].time)))
      throw std::invalid_argument(what + ": keyframe times must increase strictly (keyframe " +
                                  std::to_string(i) + " at t = " + std::to_string(f.time) + ")");
  }
}

std::vector<Keyframe> load_keyframes_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in)
    throw std::runtime_error("motion file '" + path +
                             "' not found: check the path (a relative path is looked up beside the config file, then "
                             "in the working directory)");
  std::vector<Keyframe> keys;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ss(line);
    // A row is time, position and orientation (w, x, y, z), read straight into a Keyframe.
    Keyframe k;
    bool complete = static_cast<bool>(ss >> k.time);
    for (double& c : k.position) complete = complete && static_cast<bool>(ss >> c);
    for (double& c : k.orientation) complete = complete && static_cast<bool>(ss >> c);
    if (!complete) {
      if (keys.empty() && line_no == 1) continue;  // header line
      throw std::runtime_error(path + ":" + std::to_string(line_no) +
                               ": expected 8 numbers 'time,x,y,z,qw,qx,qy,qz'");
    }
    keys.push_back(k);
  }
  if (keys.empty())
    throw std::runtime_error("motion file '" + path + "' has no rows; give rows 'time,x,y,z,qw,qx,qy,qz'");
  try {
    validate_keyframes(keys, path);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(e.what());
  }
  return keys;
}

MotionSource read_motion(const YAML::Node& node, const std::string& path) {
  namespace cfg = config;
  MotionSource src;
  Trajectory& tr = src.trajectory;
  const bool cubic_default = tr.interpolation == Trajectory::Interpolation::cubic;
  tr.interpolation = cfg::get_choice(node, path, "interpolation", {"linear", "cubic"},
                                     cubic_default ? "cubic" : "linear") == "cubic"
                         ? Trajectory::Interpolation::cubic
                         : Trajectory::Interpolation::linear;
  const YAML::Node list = node["keyframes"];
  if (static_cast<bool>(list) == static_cast<bool>(node["csv"]))
    throw cfg::ConfigError(path + ": give exactly one of keyframes or csv");
  if (!list) {
    src.csv = cfg::get_string(node, path, "csv");
    return src;
  }
  const std::string kp = path + ".keyframes";
  if (!list.IsSequence() || list.size() == 0)
    throw cfg::ConfigError(kp + ": give a list of {time, position, orientation}");
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string p = element(kp, i);
    cfg::check_keys(list[i], p, {"time", "position", "orientation"});
    Keyframe f;
    f.time = cfg::get_double(list[i], p, "time");
    const auto x = cfg::get_vector(list[i], p, "position", 3);
    f.position = {x[0], x[1], x[2]};
    if (list[i]["orientation"]) {
      const auto q = cfg::get_vector(list[i], p, "orientation", 4);
      f.orientation = {q[0], q[1], q[2], q[3]};
    }
    tr.keyframes.push_back(f);
  }
  try {
    validate_keyframes(tr.keyframes, kp);
  } catch (const std::invalid_argument& e) {
    throw cfg::ConfigError(e.what());
  }
  return src;
}

Trajectory load_motion(const MotionSource& source, const std::string& path,
                       const std::string& config_dir) {
  Trajectory tr = source.trajectory;
  if (source.csv.empty()) return tr;
  try {
    tr.keyframes = load_keyframes_csv(input_path(config_dir, source.csv));
  } catch (const std::runtime_error& e) {
    throw config::ConfigError(path + ".csv: " + e.what());
  }
  return tr;
}

Trajectory read_trajectory(const YAML::Node& node, const std::string& path,
                           const std::string& config_dir) {
  return load_motion(read_motion(node, path), path, config_dir);
}

}  // namespace cosim
