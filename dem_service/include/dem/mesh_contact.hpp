// Sphere against triangle mesh: closest point with face/edge/vertex classification, and the
// rule that leaves exactly one contact per touched feature (see docs/physics.md, "Mesh
// contacts"). The broad phase also uses the distance routine.
#pragma once

#include <cstdint>

#include "dem/mesh.hpp"
#include "dem/vec3.hpp"

namespace dem {

enum class FeatureKind : std::uint8_t { wall = 0, face = 1, edge = 2, vertex = 3 };

struct TriangleHit {
  Vec3 point;         // closest point on the triangle, world frame
  double dist2 = 0;   // squared distance from the sphere centre
  FeatureKind kind = FeatureKind::face;
  std::int32_t feature = 0;   // triangle, edge or vertex id in the mesh
  std::int32_t triangle = 0;  // triangle that reported it
};

// Closest point of triangle `tri` (world vertices `wv`) to c. Edge points are recomputed on
// the edge with its lower vertex id first, and vertex points are the vertex itself, so two
// triangles that share a feature report bit-identical points for it.
TriangleHit closest_on_triangle(const Mesh& mesh, const Vec3* wv, std::int32_t tri, Vec3 c);

// Bit l set where triangle tri[l] (l < n, 1 <= n <= 4) has its closest point to c at a squared
// distance below reach2, decided as closest_on_triangle(...).dist2 < reach2 decides it, bit for
// bit: with AVX2 on 4 triangles at a time (mesh_contact_avx2.cpp), else one by one.
int triangles_within(const Mesh& mesh, const Vec3* wv, const std::int32_t* tri, int n, Vec3 c,
                     double reach2);
// Whether triangles_within runs in lanes here (AVX2 and a GCC build on x86-64).
bool triangles_within_lanes_available();

// hits: the triangles of ONE mesh within contact distance of one sphere. Keeps a face hit
// always; keeps an edge or vertex hit only if every triangle sharing that feature reported
// the same feature (otherwise a neighbouring face or edge is closer and carries the contact),
// and only once per feature. Compacts hits in place and returns the number kept.
int select_mesh_contacts(const Mesh& mesh, TriangleHit* hits, int n);

// Vertex ids of a feature (3 for a face, 2 for an edge, 1 for a vertex); returns the count.
int feature_vertices(const Mesh& mesh, FeatureKind kind, std::int32_t id, std::int32_t out[3]);

// Key of a boundary contact: kind, wall or tool index, feature id.
inline std::uint64_t contact_key(FeatureKind kind, std::uint32_t body, std::uint32_t feature) {
  return (static_cast<std::uint64_t>(kind) << 62) |
         (static_cast<std::uint64_t>(body & 0x3FFFFFFF) << 32) | feature;
}
inline FeatureKind key_kind(std::uint64_t k) { return static_cast<FeatureKind>(k >> 62); }
inline std::uint32_t key_body(std::uint64_t k) {
  return static_cast<std::uint32_t>((k >> 32) & 0x3FFFFFFF);
}
inline std::int32_t key_feature(std::uint64_t k) {
  return static_cast<std::int32_t>(k & 0xFFFFFFFF);
}

}  // namespace dem
