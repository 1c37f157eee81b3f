#include "dem/mesh.hpp"
#include "dem/stl.hpp"

#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <map>
#include <stdexcept>
#include <tuple>
#include <unordered_map>

namespace dem {
namespace {

struct PosKey {
  std::uint64_t a, b, c;
  bool operator==(const PosKey& o) const { return a == o.a && b == o.b && c == o.c; }
};
struct PosHash {
  std::size_t operator()(const PosKey& k) const {
    return (k.a * 0x9E3779B97F4A7C15ull) ^ (k.b * 0xC2B2AE3D27D4EB4Full) ^ (k.c + 0x165667B1);
  }
};

}  // namespace

Mesh build_mesh(const std::vector<Vec3>& corners, const std::string& source) {
  if (corners.empty() || corners.size() % 3 != 0)
    throw std::runtime_error("mesh '" + source + "': no triangles; export the tool as a closed "
                             "or open triangle surface (STL, OBJ, PLY)");
  for (std::size_t k = 0; k < corners.size(); ++k) {
    const Vec3& p = corners[k];
    if (!(std::abs(p.x) <= kMaxMeshCoordinate && std::abs(p.y) <= kMaxMeshCoordinate &&
          std::abs(p.z) <= kMaxMeshCoordinate)) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "triangle %zu corner %zu is at (%.9g, %.9g, %.9g)", k / 3,
                    k % 3, p.x, p.y, p.z);
      throw std::runtime_error("mesh '" + source + "': " + buf +
                               ": not a finite point within 1e6 m of the reference point; fix "
                               "the mesh or its units");
    }
  }
  Mesh m;
  m.source = source;
  // STL stores every triangle's corners separately, and exporters round: weld corners closer
  // than 1e-9 of the mesh size so shared edges and vertices are recognised as one feature.
  Vec3 lo = corners[0], hi = corners[0];
  for (const Vec3& p : corners) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  // The floor keeps v / tol within int64 for every coordinate allowed (|v| <= 1e6 m, checked
  // above): a sub-millimetre mesh welds at 1e-12 m. Cells are signed, stored as their two's
  // complement (converting a negative double straight to uint64 is undefined; found by
  // tests/fuzz/fuzz_stl).
  const double tol = std::max(1e-9 * norm(hi - lo), 1e-12);
  std::unordered_map<PosKey, std::vector<std::int32_t>, PosHash> index;
  auto cell = [&](double v) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(v / tol)));
  };
  auto vertex_id = [&](Vec3 p) {
    const std::uint64_t cx = cell(p.x), cy = cell(p.y), cz = cell(p.z);
    for (std::uint64_t dx = cx - 1; dx != cx + 2; ++dx)
      for (std::uint64_t dy = cy - 1; dy != cy + 2; ++dy)
        for (std::uint64_t dz = cz - 1; dz != cz + 2; ++dz) {
          const auto it = index.find(PosKey{dx, dy, dz});
          if (it == index.end()) continue;
          for (std::int32_t v : it->second)
            if (norm2(m.vertices[v] - p) <= tol * tol) return v;
        }
    const auto id = static_cast<std::int32_t>(m.vertices.size());
    m.vertices.push_back(p);
    index[PosKey{cx, cy, cz}].push_back(id);
    return id;
  };
  std::map<std::pair<std::int32_t, std::int32_t>, std::int32_t> edge_id;
  for (std::size_t t = 0; t < corners.size() / 3; ++t) {
    std::array<std::int32_t, 3> tri{vertex_id(corners[3 * t]), vertex_id(corners[3 * t + 1]),
                                    vertex_id(corners[3 * t + 2])};
    const Vec3 a = m.vertices[tri[0]], b = m.vertices[tri[1]], c = m.vertices[tri[2]];
    const double area2 = norm(cross(b - a, c - a));
    const double scale = std::max({norm2(b - a), norm2(c - a), norm2(c - b)});
    if (!(area2 > 1e-12 * scale)) continue;  // zero-area triangles carry no contact
    std::array<std::int32_t, 3> te{};
    for (int e = 0; e < 3; ++e) {
      std::int32_t u = tri[e], w = tri[(e + 1) % 3];
      if (u > w) std::swap(u, w);
      auto [it, inserted] =
          edge_id.emplace(std::make_pair(u, w), static_cast<std::int32_t>(m.edges.size()));
      if (inserted) m.edges.push_back({u, w});
      te[e] = it->second;
    }
    m.triangles.push_back(tri);
    m.triangle_edges.push_back(te);
  }
  if (m.triangles.empty())
    throw std::runtime_error("mesh '" + source + "': every triangle has zero area; check the "
                             "export units and scale");
  m.edge_valence.assign(m.edges.size(), 0);
  m.vertex_valence.assign(m.vertices.size(), 0);
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    for (int e = 0; e < 3; ++e) {
      ++m.edge_valence[m.triangle_edges[t][e]];
      ++m.vertex_valence[m.triangles[t][e]];
    }
  for (const Vec3& p : m.vertices) m.bounding_radius = std::max(m.bounding_radius, norm(p));
  return m;
}

namespace {

// Corners of every triangle of an assimp scene, scaled and relative to reference_point; a
// corner that is not finite or lies absurdly far is named (triangle, corner, value).
std::vector<Vec3> scene_corners(const aiScene* scene, const std::string& path, double scale,
                                Vec3 reference_point) {
  std::vector<Vec3> corners;
  for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
    const aiMesh* mesh = scene->mMeshes[mi];
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines are not surfaces
      for (int k = 0; k < 3; ++k) {
        const aiVector3D& p = mesh->mVertices[face.mIndices[k]];
        const Vec3 v = Vec3{scale * p.x, scale * p.y, scale * p.z} - reference_point;
        if (!(std::abs(v.x) <= kMaxMeshCoordinate && std::abs(v.y) <= kMaxMeshCoordinate &&
              std::abs(v.z) <= kMaxMeshCoordinate)) {
          char buf[256];
          std::snprintf(buf, sizeof buf,
                        "mesh file '%s': triangle %zu corner %d is at (%.9g, %.9g, %.9g) in the "
                        "file", path.c_str(), corners.size() / 3, k, static_cast<double>(p.x),
                        static_cast<double>(p.y), static_cast<double>(p.z));
          const bool finite = std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
          throw std::runtime_error(std::string(buf) +
                                   (finite ? ", more than 1e6 m from the reference point after "
                                             "tools[].scale: check the export units and the scale"
                                           : ": not a finite number; fix or re-export the mesh"));
        }
        corners.push_back(v);
      }
    }
  }
  return corners;
}

}  // namespace

Mesh load_mesh(const std::string& path, double scale, Vec3 reference_point) {
  if (!std::filesystem::exists(path))
    throw std::runtime_error("mesh file '" + path + "' not found: check tools[].mesh (relative "
                             "paths are resolved against the config file's folder)");
  if (std::filesystem::is_directory(path))
    throw std::runtime_error("mesh file '" + path + "' is a folder: name the mesh file in it");
  std::string bytes;
  if (is_stl_path(path)) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    bytes = s.str();
  }
  return load_mesh_data(bytes, path, scale, reference_point);
}

Mesh load_mesh_data(const std::string& stl_bytes, const std::string& path, double scale,
                    Vec3 reference_point) {
  Assimp::Importer importer;
  const unsigned flags = aiProcess_Triangulate | aiProcess_PreTransformVertices;
  const bool stl = is_stl_path(path);
  if (stl) read_stl(stl_bytes, path);  // names what assimp would read silently or wrongly
  const aiScene* scene =
      stl ? importer.ReadFileFromMemory(stl_bytes.data(), stl_bytes.size(), flags, "stl")
          : importer.ReadFile(path, flags);
  if (!scene || !scene->mRootNode || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE))
    throw std::runtime_error("mesh file '" + path + "' could not be read (" +
                             importer.GetErrorString() +
                             "): re-export it as STL, OBJ or PLY with triangle faces");
  const std::vector<Vec3> corners = scene_corners(scene, path, scale, reference_point);
  if (corners.empty())
    throw std::runtime_error("mesh file '" + path + "' has no triangles: re-export it as a "
                             "triangulated surface (STL, OBJ or PLY)");
  return build_mesh(corners, path);
}

}  // namespace dem
