#include "dem/mesh.hpp"

#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
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
  Mesh m;
  m.source = source;
  // STL stores every triangle's corners separately, and exporters round: weld corners closer
  // than 1e-9 of the mesh size so shared edges and vertices are recognised as one feature.
  Vec3 lo = corners[0], hi = corners[0];
  for (const Vec3& p : corners) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  const double tol = std::max(1e-9 * norm(hi - lo), 1e-300);
  std::unordered_map<PosKey, std::vector<std::int32_t>, PosHash> index;
  auto cell = [&](double v) { return static_cast<std::uint64_t>(std::floor(v / tol)); };
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

Mesh load_mesh(const std::string& path, double scale, Vec3 reference_point) {
  if (!std::filesystem::exists(path))
    throw std::runtime_error("mesh file '" + path + "' not found: check tools[].mesh (relative "
                             "paths are resolved against the config file's folder)");
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(path, aiProcess_Triangulate |
                                                     aiProcess_PreTransformVertices);
  if (!scene || !scene->mRootNode || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE))
    throw std::runtime_error("mesh file '" + path + "' could not be read (" +
                             importer.GetErrorString() +
                             "): re-export it as STL, OBJ or PLY with triangle faces");
  std::vector<Vec3> corners;
  for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
    const aiMesh* mesh = scene->mMeshes[mi];
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines are not surfaces
      for (int k = 0; k < 3; ++k) {
        const aiVector3D& p = mesh->mVertices[face.mIndices[k]];
        corners.push_back(Vec3{scale * p.x, scale * p.y, scale * p.z} - reference_point);
      }
    }
  }
  if (corners.empty())
    throw std::runtime_error("mesh file '" + path + "' has no triangles: re-export it as a "
                             "triangulated surface (STL, OBJ or PLY)");
  return build_mesh(corners, path);
}

}  // namespace dem
