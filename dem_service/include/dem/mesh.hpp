// Triangle mesh of a rigid tool with the topology that mesh contacts need: welded vertices,
// unique edges, and how many triangles share each edge and vertex (the feature valence).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "dem/vec3.hpp"

namespace dem {

struct Mesh {
  std::string source;            // file it came from, for messages
  std::vector<Vec3> vertices;    // mesh frame, relative to the tool's reference point
  std::vector<std::array<std::int32_t, 3>> triangles;
  std::vector<std::array<std::int32_t, 3>> triangle_edges;  // edges (v0v1, v1v2, v2v0)
  std::vector<std::array<std::int32_t, 2>> edges;           // vertex ids, lower first
  std::vector<std::int32_t> edge_valence;                   // triangles sharing each edge
  std::vector<std::int32_t> vertex_valence;                 // triangles sharing each vertex
  double bounding_radius = 0;    // max distance of a vertex from the reference point
};

// Builds the topology from triangle corners (3 per triangle, mesh frame). Corners at exactly
// the same position are welded into one vertex; degenerate triangles are refused.
Mesh build_mesh(const std::vector<Vec3>& corners, const std::string& source);

// Loads STL, OBJ, PLY (anything assimp reads), scales it and stores it relative to
// reference_point (given in the file's frame, after scaling). Throws std::runtime_error naming
// the file and the fix when the file is missing, unreadable or has no triangles.
// A .stl file is first read strictly (dem/stl.hpp): a truncated file or a vertex that is not a
// finite float is named. Any format: a corner that is not finite or lies more than
// kMaxMeshCoordinate from the reference point after scaling is named (triangle, corner, value).
Mesh load_mesh(const std::string& path, double scale, Vec3 reference_point);
// load_mesh on bytes in memory when `path` names an STL (path is used for its extension and in
// messages); other formats are read from the file at path and stl_bytes is ignored.
Mesh load_mesh_data(const std::string& stl_bytes, const std::string& path, double scale,
                    Vec3 reference_point);

inline constexpr double kMaxMeshCoordinate = 1e6;  // m

}  // namespace dem
