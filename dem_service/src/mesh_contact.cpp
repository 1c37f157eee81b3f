#include "dem/mesh_contact.hpp"

namespace dem {
namespace {

TriangleHit vertex_hit(const Vec3* wv, std::int32_t v, std::int32_t tri, Vec3 c) {
  TriangleHit h;
  h.point = wv[v];
  h.dist2 = norm2(c - h.point);
  h.kind = FeatureKind::vertex;
  h.feature = v;
  h.triangle = tri;
  return h;
}

TriangleHit edge_hit(const Mesh& mesh, const Vec3* wv, std::int32_t e, std::int32_t tri, Vec3 c) {
  const auto [u, w] = mesh.edges[e];
  const Vec3 a = wv[u], d = wv[w] - wv[u];
  const double t = dot(c - a, d) / norm2(d);
  if (t <= 0) return vertex_hit(wv, u, tri, c);
  if (t >= 1) return vertex_hit(wv, w, tri, c);
  TriangleHit h;
  h.point = a + t * d;
  h.dist2 = norm2(c - h.point);
  h.kind = FeatureKind::edge;
  h.feature = e;
  h.triangle = tri;
  return h;
}

}  // namespace

TriangleHit closest_on_triangle(const Mesh& mesh, const Vec3* wv, std::int32_t tri, Vec3 c) {
  const auto& T = mesh.triangles[tri];
  const auto& E = mesh.triangle_edges[tri];
  const Vec3 a = wv[T[0]], b = wv[T[1]], cc = wv[T[2]];
  const Vec3 ab = b - a, ac = cc - a;
  // Voronoi regions of the triangle, tested vertex by vertex, then edges, then the face.
  const Vec3 ap = c - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return vertex_hit(wv, T[0], tri, c);
  const Vec3 bp = c - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return vertex_hit(wv, T[1], tri, c);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return edge_hit(mesh, wv, E[0], tri, c);
  const Vec3 cp = c - cc;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return vertex_hit(wv, T[2], tri, c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return edge_hit(mesh, wv, E[2], tri, c);
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return edge_hit(mesh, wv, E[1], tri, c);
  const double inv = 1.0 / (va + vb + vc);
  TriangleHit h;
  h.point = a + (vb * inv) * ab + (vc * inv) * ac;
  h.dist2 = norm2(c - h.point);
  h.kind = FeatureKind::face;
  h.feature = tri;
  h.triangle = tri;
  return h;
}

int select_mesh_contacts(const Mesh& mesh, TriangleHit* hits, int n) {
  // First decide every hit (counting needs the untouched list), then compact.
  for (int a = 0; a < n; ++a) {
    TriangleHit& h = hits[a];
    if (h.kind == FeatureKind::face) continue;
    int reported = 0;
    bool first = true;
    for (int b = 0; b < n; ++b)
      if (hits[b].kind == h.kind && hits[b].feature == h.feature) {
        ++reported;
        if (b < a) first = false;
      }
    const int valence = h.kind == FeatureKind::edge ? mesh.edge_valence[h.feature]
                                                    : mesh.vertex_valence[h.feature];
    if (!first || reported != valence) h.triangle = -1 - h.triangle;  // mark dropped
  }
  int kept = 0;
  for (int a = 0; a < n; ++a)
    if (hits[a].triangle >= 0) hits[kept++] = hits[a];
  return kept;
}

int feature_vertices(const Mesh& mesh, FeatureKind kind, std::int32_t id, std::int32_t out[3]) {
  switch (kind) {
    case FeatureKind::face:
      for (int k = 0; k < 3; ++k) out[k] = mesh.triangles[id][k];
      return 3;
    case FeatureKind::edge:
      out[0] = mesh.edges[id][0];
      out[1] = mesh.edges[id][1];
      return 2;
    case FeatureKind::vertex:
      out[0] = id;
      return 1;
    default:
      return 0;
  }
}

}  // namespace dem
