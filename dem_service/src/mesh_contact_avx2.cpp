// The boundary contacts' triangle test on 4 candidate triangles at a time (AVX2, where the
// processor has it): which of a sphere's candidate triangles have their closest point within
// reach, decided as closest_on_triangle (mesh_contact.cpp) decides it. Every lane runs that
// function's operations on the same operands in the same order (IEEE add, sub, mul and div, no
// fused multiply-add: the engine is built with -ffp-contract=off), its branches as selects: the
// Voronoi region of the triangle (vertices, edges, then the face, in the function's order), and
// the squared distance to the point that region gives (an edge's point on the edge with its
// lower vertex id first, as edge_hit takes it). So the same decisions, bit for bit
// (dem_MeshContact.TrianglesWithinDecideAsTheClosestPoint, dem_BoundaryFast.*). The caller then
// runs closest_on_triangle on the triangles within reach only (about 1 in 6 candidates in the
// main job's DEM). Written with GCC's vector extensions; elsewhere the scalar function decides.
#include <algorithm>

#include "dem/mesh_contact.hpp"

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define DEM_HAVE_AVX2_TRIANGLES 1
#endif

namespace dem {

#ifdef DEM_HAVE_AVX2_TRIANGLES
namespace {

typedef double v4d __attribute__((vector_size(32)));
typedef long long v4q __attribute__((vector_size(32)));
#define DEM_AVX2_INLINE __attribute__((target("avx2"), always_inline)) inline

DEM_AVX2_INLINE v4d splat(double a) { return v4d{a, a, a, a}; }
DEM_AVX2_INLINE int lanes_of(v4q m) { return __builtin_ia32_movmskpd256(reinterpret_cast<v4d>(m)); }

struct V4 {  // a Vec3 in 4 lanes
  v4d x, y, z;
};
DEM_AVX2_INLINE V4 sub(V4 a, V4 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
DEM_AVX2_INLINE v4d dot(V4 a, V4 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
DEM_AVX2_INLINE V4 lanes(const Vec3* wv, const std::int32_t* v) {
  return {v4d{wv[v[0]].x, wv[v[1]].x, wv[v[2]].x, wv[v[3]].x},
          v4d{wv[v[0]].y, wv[v[1]].y, wv[v[2]].y, wv[v[3]].y},
          v4d{wv[v[0]].z, wv[v[1]].z, wv[v[2]].z, wv[v[3]].z}};
}
DEM_AVX2_INLINE V4 select(v4q m, V4 a, V4 b) {
  return {m ? a.x : b.x, m ? a.y : b.y, m ? a.z : b.z};
}

// The lanes of `open` that pass `test` (their region), no longer open after it.
DEM_AVX2_INLINE v4q take_region(v4q& open, v4q test) {
  const v4q taken = open & test;
  open &= ~test;
  return taken;
}

__attribute__((target("avx2"))) int within_avx2(const Mesh& mesh, const Vec3* wv,
                                                const std::int32_t* tri, int n, Vec3 c,
                                                double reach2) {
  std::int32_t t[4], va_[4], vb_[4], vc_[4];
  for (int l = 0; l < 4; ++l) {
    t[l] = tri[std::min(l, n - 1)];  // lanes past n repeat the last triangle
    const auto& T = mesh.triangles[static_cast<std::size_t>(t[l])];
    va_[l] = T[0];
    vb_[l] = T[1];
    vc_[l] = T[2];
  }
  const V4 C{splat(c.x), splat(c.y), splat(c.z)};
  const V4 a = lanes(wv, va_), b = lanes(wv, vb_), cc = lanes(wv, vc_);
  const V4 ab = sub(b, a), ac = sub(cc, a);
  const v4d zero = splat(0.0), one = splat(1.0);
  // The regions in closest_on_triangle's order: a lane takes the first whose test it passes.
  v4q open = ~v4q{};  // the lanes no region has taken yet
  const V4 ap = sub(C, a);
  const v4d d1 = dot(ab, ap), d2 = dot(ac, ap);
  const v4q in_a = take_region(open, (d1 <= zero) & (d2 <= zero));
  const V4 bp = sub(C, b);
  const v4d d3 = dot(ab, bp), d4 = dot(ac, bp);
  const v4q in_b = take_region(open, (d3 >= zero) & (d4 <= d3));
  const v4d vc = d1 * d4 - d3 * d2;
  const v4q in_ab = take_region(open, (vc <= zero) & (d1 >= zero) & (d3 <= zero));
  const V4 cp = sub(C, cc);
  const v4d d5 = dot(ab, cp), d6 = dot(ac, cp);
  const v4q in_c = take_region(open, (d6 >= zero) & (d5 <= d6));
  const v4d vb = d5 * d2 - d1 * d6;
  const v4q in_ca = take_region(open, (vb <= zero) & (d2 >= zero) & (d6 <= zero));
  const v4d va = d3 * d6 - d5 * d4;
  const v4q in_bc = take_region(open, (va <= zero) & ((d4 - d3) >= zero) & ((d5 - d6) >= zero));
  const v4q in_face = open;
  // A vertex's distance: the vertex itself is the point (vertex_hit).
  v4d dist2 = in_a ? dot(ap, ap) : zero;
  dist2 = in_b ? dot(bp, bp) : dist2;
  dist2 = in_c ? dot(cp, cp) : dist2;
  // The face's point.
  if (lanes_of(in_face)) {
    const v4d inv = one / (va + vb + vc);
    const v4d sb = vb * inv, sc = vc * inv;
    const V4 p{a.x + sb * ab.x + sc * ac.x, a.y + sb * ab.y + sc * ac.y,
               a.z + sb * ab.z + sc * ac.z};
    const V4 cq = sub(C, p);
    dist2 = in_face ? dot(cq, cq) : dist2;
  }
  // An edge's point (edge_hit): on the edge as the mesh stores it, its lower vertex first.
  const v4q on_edge = in_ab | in_ca | in_bc;
  const int edge_lanes = lanes_of(on_edge);
  if (edge_lanes) {
    const int ab_lanes = lanes_of(in_ab), ca_lanes = lanes_of(in_ca);
    std::int32_t u[4], w[4];
    for (int l = 0; l < 4; ++l) {
      const auto& E = mesh.triangle_edges[static_cast<std::size_t>(t[l])];
      const std::int32_t e = ab_lanes >> l & 1 ? E[0] : (ca_lanes >> l & 1 ? E[2] : E[1]);
      u[l] = mesh.edges[static_cast<std::size_t>(e)][0];
      w[l] = mesh.edges[static_cast<std::size_t>(e)][1];
    }
    const V4 eu = lanes(wv, u), ew = lanes(wv, w);
    const V4 d = sub(ew, eu);
    const V4 cu = sub(C, eu);
    const v4d te = dot(cu, d) / dot(d, d);
    const V4 p{eu.x + te * d.x, eu.y + te * d.y, eu.z + te * d.z};
    const V4 cw = sub(C, ew);
    const V4 cq = sub(C, p);
    v4d de = dot(cq, cq);
    de = te >= one ? dot(cw, cw) : de;
    de = te <= zero ? dot(cu, cu) : de;
    dist2 = on_edge ? de : dist2;
  }
  const int valid = (1 << n) - 1;
  return lanes_of(dist2 < splat(reach2)) & valid;
}

}  // namespace

bool triangles_within_lanes_available() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2");
}

int triangles_within(const Mesh& mesh, const Vec3* wv, const std::int32_t* tri, int n, Vec3 c,
                     double reach2) {
  return within_avx2(mesh, wv, tri, n, c, reach2);
}
#else
bool triangles_within_lanes_available() { return false; }

int triangles_within(const Mesh& mesh, const Vec3* wv, const std::int32_t* tri, int n, Vec3 c,
                     double reach2) {
  int within = 0;
  for (int l = 0; l < n; ++l)
    within |= (closest_on_triangle(mesh, wv, tri[l], c).dist2 < reach2) << l;
  return within;
}
#endif

}  // namespace dem
