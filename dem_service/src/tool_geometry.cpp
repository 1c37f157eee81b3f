#include "dem/tool_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "dem/engine_types.hpp"

namespace dem {

ToolGeometry::ToolGeometry(const Scene& scene) {
  vertices.resize(scene.tools.size());
  rotation.resize(scene.tools.size());
  for (const auto& tool : scene.tools) {
    Vec3 lo{0, 0, 0}, hi{0, 0, 0};
    if (!tool.mesh.vertices.empty()) lo = hi = tool.mesh.vertices[0];
    for (const Vec3& v : tool.mesh.vertices) {
      lo = {std::min(lo.x, v.x), std::min(lo.y, v.y), std::min(lo.z, v.z)};
      hi = {std::max(hi.x, v.x), std::max(hi.y, v.y), std::max(hi.z, v.z)};
    }
    box_min.push_back(lo);
    box_max.push_back(hi);
    // The box's farthest corner from the reference point (the mesh frame's origin).
    const Vec3 far{std::max(std::abs(lo.x), std::abs(hi.x)), std::max(std::abs(lo.y), std::abs(hi.y)),
                   std::max(std::abs(lo.z), std::abs(hi.z))};
    box_radius.push_back(norm(far));
  }
}

void ToolGeometry::update(const Scene& scene, const State& s) {
  if (s.tool_pose.size() != scene.tools.size())
    throw SimulationError("state has " + std::to_string(s.tool_pose.size()) +
                          " tool poses but the scene has " + std::to_string(scene.tools.size()) +
                          " tools");
  for (std::size_t m = 0; m < scene.tools.size(); ++m) {
    const Mesh& mesh = scene.tools[m].mesh;
    const ToolPose& pose = s.tool_pose[m];
    const Mat3 R = to_matrix(pose.orientation);
    rotation[m] = R;
    auto& wv = vertices[m];
    wv.resize(mesh.vertices.size());
    for (std::size_t v = 0; v < wv.size(); ++v) wv[v] = pose.position + R * mesh.vertices[v];
  }
}

std::size_t ToolGeometry::bytes() const {
  std::size_t b = 0;
  for (const auto& v : vertices) b += v.capacity() * sizeof(Vec3);
  return b;
}

}  // namespace dem
