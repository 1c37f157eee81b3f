#include "body_mesh.hpp"

#include "stl.hpp"

#include <cmath>
#include <cstdint>
#include <map>
#include <stdexcept>
#include <tuple>

namespace hauler {

namespace {

int pieces(double length, double h) { return std::max(1, static_cast<int>(std::ceil(length / h - 1e-9))); }

// i-th of n points from a to b, ending exactly on b (seam vertices of two plates then agree
// bit for bit).
double at(double a, double b, int i, int n) { return i == n ? b : a + (b - a) * i / n; }

struct Builder {
  BodyMesh& m;
  std::map<std::tuple<double, double, double>, int> index;
  int vertex(const Point& p) {
    const auto key = std::make_tuple(p[0], p[1], p[2]);
    const auto it = index.find(key);
    if (it != index.end()) return it->second;
    const int id = static_cast<int>(m.vertices.size());
    m.vertices.push_back(p);
    index.emplace(key, id);
    return id;
  }
  // A plate through the grid point(i, j), i = 0..nu, j = 0..nv; its triangles' normals are
  // along (point(1,0) - point(0,0)) x (point(0,1) - point(0,0)).
  template <class F>
  void plate(int nu, int nv, F point) {
    std::vector<int> id((nu + 1) * (nv + 1));
    for (int i = 0; i <= nu; ++i)
      for (int j = 0; j <= nv; ++j) id[i * (nv + 1) + j] = vertex(point(i, j));
    auto v = [&](int i, int j) { return id[i * (nv + 1) + j]; };
    for (int i = 0; i < nu; ++i)
      for (int j = 0; j < nv; ++j) {
        m.triangles.push_back({v(i, j), v(i + 1, j), v(i, j + 1)});
        m.triangles.push_back({v(i + 1, j), v(i + 1, j + 1), v(i, j + 1)});
      }
  }
};

}  // namespace

BodyMesh make_body_mesh(const BodyShape& s, double element) {
  if (!(element >= 0.02 && element <= 1))
    throw std::invalid_argument("element size must be in [0.02, 1] m");
  BodyMesh m;
  m.nx = pieces(s.length, element);
  m.ny = pieces(s.width, element);
  m.nz = pieces(s.side_height, element);
  const double x0 = s.tail_x, x1 = s.front_x();
  const double y0 = -0.5 * s.width, y1 = 0.5 * s.width;
  const double z0 = s.floor_z, z1 = s.floor_z + s.side_height;
  const int nx = m.nx, ny = m.ny, nz = m.nz;
  Builder b{m, {}};
  // floor: x then y, normal x cross y = +z (up, into the load)
  b.plate(nx, ny, [&](int i, int j) { return Point{at(x0, x1, i, nx), at(y0, y1, j, ny), z0}; });
  // front wall: z then y, normal z cross y = -x (backwards, into the load)
  b.plate(nz, ny, [&](int i, int j) { return Point{x1, at(y0, y1, j, ny), at(z0, z1, i, nz)}; });
  // left wall (y = +W/2): x then z, normal x cross z = -y
  b.plate(nx, nz, [&](int i, int j) { return Point{at(x0, x1, i, nx), y1, at(z0, z1, j, nz)}; });
  // right wall (y = -W/2): z then x, normal z cross x = +y
  b.plate(nz, nx, [&](int i, int j) { return Point{at(x0, x1, j, nx), y0, at(z0, z1, i, nz)}; });
  m.volume = s.volume();
  return m;
}

void write_stl(const BodyMesh& m, const std::string& path) {
  mbs::write_binary_stl(m.vertices, m.triangles, "soilcosim body_mesh: hauler body frame, origin hinge axis, metres", path);
}

}  // namespace hauler
