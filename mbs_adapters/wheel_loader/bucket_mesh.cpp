#include "bucket_mesh.hpp"

#include "stl.hpp"

#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace wheel_loader {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct P2 {
  double x, z;
};

int pieces(double length, double h) { return std::max(1, static_cast<int>(std::ceil(length / h - 1e-9))); }

void line(std::vector<P2>& out, P2 a, P2 b, double h) {  // appends b side points, not a
  const int n = pieces(std::hypot(b.x - a.x, b.z - a.z), h);
  for (int i = 1; i <= n; ++i) out.push_back({a.x + (b.x - a.x) * i / n, a.z + (b.z - a.z) * i / n});
}

}  // namespace

BucketMesh make_bucket_mesh(const BucketShape& s, int refine) {
  if (refine < 1 || refine > kMaxRefine)
    throw std::invalid_argument("refine must be 1.." + std::to_string(kMaxRefine));
  const double h = 0.1 / refine;
  const double R = s.heel_radius;
  const P2 V{s.edge_x - s.edge_depth, s.floor_z - s.edge_thickness};  // bevel's back edge
  const P2 E{s.edge_x, s.floor_z};                                      // cutting-edge tip
  const P2 H{s.back_x + R, s.floor_z};
  const P2 B{s.back_x, s.back_top_z};
  const double a = s.guard_angle * kPi / 180;
  const P2 G{B.x + s.guard_length * std::cos(a), B.z + s.guard_length * std::sin(a)};

  // The profile from the bevel's back edge through the tip, floor, heel, back to the guard.
  std::vector<P2> prof{V};
  line(prof, V, E, h);
  const int iE = static_cast<int>(prof.size()) - 1;
  line(prof, E, H, h);
  const int n_arc = pieces(0.5 * kPi * R, h);
  for (int i = 1; i <= n_arc; ++i) {  // heel: centre (back_x + R, floor_z + R), -90 -> -180 deg
    const double t = -0.5 * kPi - 0.5 * kPi * i / n_arc;
    prof.push_back({H.x + R * std::cos(t), s.floor_z + R + R * std::sin(t)});
  }
  line(prof, prof.back(), B, h);
  if (s.guard_length > 0) line(prof, B, G, h);
  const P2 top = prof.back();

  BucketMesh m;
  const int np = static_cast<int>(prof.size());
  const int nw = pieces(s.width, h);
  auto vid = [&](int i, int j) { return i * (nw + 1) + j; };
  for (int i = 0; i < np; ++i)
    for (int j = 0; j <= nw; ++j)
      m.vertices.push_back({prof[i].x, -0.5 * s.width + s.width * j / nw, prof[i].z});
  // normal = y x tangent: up on the floor, forward on the back plate (the soil side)
  for (int i = 0; i + 1 < np; ++i)
    for (int j = 0; j < nw; ++j) {
      m.triangles.push_back({vid(i, j), vid(i, j + 1), vid(i + 1, j)});
      m.triangles.push_back({vid(i + 1, j), vid(i, j + 1), vid(i + 1, j + 1)});
    }

  // Side plates: the polygon tip -> ... -> guard top, closed by the straight front edge,
  // meshed in rings towards its centroid (it is convex).
  std::vector<P2> loop(prof.begin() + iE, prof.end());
  std::vector<P2> front;
  line(front, top, E, h);
  front.pop_back();  // E is loop[0]
  const int n_profile_nodes = static_cast<int>(loop.size());
  loop.insert(loop.end(), front.begin(), front.end());
  const int nb = static_cast<int>(loop.size());
  P2 c{0, 0};
  for (const auto& p : loop) c = {c.x + p.x / nb, c.z + p.z / nb};
  const int nr = std::max(2, pieces(0.35, h));
  for (int side = 0; side < 2; ++side) {
    const double y = side == 0 ? 0.5 * s.width : -0.5 * s.width;
    const int j_strip = side == 0 ? nw : 0;
    // ring[k][b]: ring k = 1..nr (nr is the boundary), k = 0 the centre
    std::vector<std::vector<int>> ring(nr + 1, std::vector<int>(nb));
    const int centre = static_cast<int>(m.vertices.size());
    m.vertices.push_back({c.x, y, c.z});
    for (int k = 1; k <= nr; ++k)
      for (int b = 0; b < nb; ++b) {
        if (k == nr && b < n_profile_nodes) {
          ring[k][b] = vid(iE + b, j_strip);  // shared with the strip
          continue;
        }
        const double f = static_cast<double>(k) / nr;
        ring[k][b] = static_cast<int>(m.vertices.size());
        m.vertices.push_back({c.x + f * (loop[b].x - c.x), y, c.z + f * (loop[b].z - c.z)});
      }
    for (int b = 0; b < nb; ++b) ring[0][b] = centre;
    // the loop turns positively about +y (seen from +y it runs anticlockwise); inward
    // normals are -y at +W/2, so that side takes the triangles reversed
    auto tri = [&](int p, int q, int r) {
      if (side == 0) m.triangles.push_back({p, r, q});
      else m.triangles.push_back({p, q, r});
    };
    for (int k = 0; k < nr; ++k)
      for (int b = 0; b < nb; ++b) {
        const int b1 = (b + 1) % nb;
        if (k == 0) {
          tri(centre, ring[1][b], ring[1][b1]);
          continue;
        }
        tri(ring[k][b], ring[k + 1][b], ring[k + 1][b1]);
        tri(ring[k][b], ring[k + 1][b1], ring[k][b1]);
      }
  }

  // Capacity: shoelace area of the side-plate polygon times the inner width (struck), plus the
  // 2:1 heap over the strike plane of length L: W L^2 / 8 - L^3 / 24.
  double area = 0;
  for (int b = 0; b < nb; ++b) {
    const P2& p = loop[b];
    const P2& q = loop[(b + 1) % nb];
    area += p.x * q.z - q.x * p.z;
  }
  area = 0.5 * std::abs(area);
  const double L = std::hypot(top.x - E.x, top.z - E.z);
  m.struck_volume = area * s.width;
  m.heaped_volume = m.struck_volume + s.width * L * L / 8 - L * L * L / 24;
  return m;
}

void write_stl(const BucketMesh& m, const std::string& path) {
  mbs::write_binary_stl(m.vertices, m.triangles, "soilcosim bucket_mesh: bucket frame, origin A-pin, metres", path);
}

}  // namespace wheel_loader
