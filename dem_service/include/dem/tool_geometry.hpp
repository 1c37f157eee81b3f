// The tools' world geometry at the current pose (vertices, rotation) and their meshes' boxes in
// the tool frame: what the broad phase, the boundary contacts, the guard and the sleepers'
// tool neighbourhood read.
#pragma once

#include <vector>

#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem {

struct ToolGeometry {
  std::vector<std::vector<Vec3>> vertices;  // world frame, current pose
  std::vector<Mat3> rotation;
  std::vector<Vec3> box_min, box_max;  // mesh frame, for scene.sleep.neighbourhood
  std::vector<double> box_radius;      // farthest box corner from the reference point

  explicit ToolGeometry(const Scene& scene);
  // The vertices and rotations at s.tool_pose; throws SimulationError if the state's tool
  // count is not the scene's.
  void update(const Scene& scene, const State& s);
  std::size_t bytes() const;
};

// R^T d: a world-frame vector in the frame turned by R.
inline Vec3 to_frame(const Mat3& R, const Vec3& d) {
  return {R.m[0][0] * d.x + R.m[1][0] * d.y + R.m[2][0] * d.z,
          R.m[0][1] * d.x + R.m[1][1] * d.y + R.m[2][1] * d.z,
          R.m[0][2] * d.x + R.m[1][2] * d.y + R.m[2][2] * d.z};
}

}  // namespace dem
