// A rigid body's pose played from keyframes (time, position, unit quaternion): positions
// piecewise linear or C1 cubic (Catmull-Rom tangents, one-sided at the ends), orientations by
// slerp with the segment's constant angular velocity. Before the first and after the last
// keyframe the body holds still. The one implementation behind dem_run's tool motion and the
// prescribed participant (docs/dem.md, docs/prescribed.md). Bus-free: the DEM engine links it.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>
#include <vector>

#include "cosim/rotation.hpp"

namespace cosim {

struct Keyframe {
  double time = 0;
  Vec3 position{};
  Quat orientation{1, 0, 0, 0};
};

struct Pose {
  Vec3 position{}, velocity{}, angular_velocity{};  // ground frame; velocity of the point
  Quat orientation{1, 0, 0, 0};
};

struct Trajectory {
  enum class Interpolation { linear, cubic };
  Interpolation interpolation = Interpolation::linear;
  std::vector<Keyframe> keyframes;  // validated: times strictly increasing, unit quaternions
  // Pose and velocities at time t (an empty trajectory rests at the origin).
  Pose evaluate(double t) const;
};

// Checks that there is at least one keyframe, that times and positions are finite, times
// increase strictly and quaternions are not zero; normalises the quaternions. Throws
// std::invalid_argument naming `what`, the keyframe and the fix.
void validate_keyframes(std::vector<Keyframe>& keys, const std::string& what);

// Reads and validates rows "time,x,y,z,qw,qx,qy,qz" (commas or blanks; '#' comments and one
// header line allowed). Throws std::runtime_error naming the file, the line and the fix.
std::vector<Keyframe> load_keyframes_csv(const std::string& path);

// The motion keys of a config map as written: `interpolation` (linear | cubic, the default of
// Trajectory) and exactly one of `keyframes` (a list of {time, position, orientation}, read and
// validated here) or `csv` (the file name, read by load_motion). The caller checks the map's
// other keys. Throws config::ConfigError naming the dotted key; list elements are named in the
// caller's index style (`path.keyframes.1`, or `path.keyframes[1]` when path uses brackets).
struct MotionSource {
  Trajectory trajectory;  // keyframes empty when they come from `csv`
  std::string csv;        // as written; "" = keyframes given inline
};
MotionSource read_motion(const YAML::Node& node, const std::string& path);

// The trajectory of `source`, reading its CSV (found by cosim::input_path from config_dir) if
// it names one; a bad file throws config::ConfigError "<path>.csv: ...".
Trajectory load_motion(const MotionSource& source, const std::string& path,
                       const std::string& config_dir);

// read_motion, then load_motion.
Trajectory read_trajectory(const YAML::Node& node, const std::string& path,
                           const std::string& config_dir);

}  // namespace cosim
