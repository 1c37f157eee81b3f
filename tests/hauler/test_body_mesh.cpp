// The dump-body mesh: a consistently oriented shell with the rim we expect (closed seams,
// open tail and top), normals into the load, the box's cavity volume by the divergence
// theorem, bounding box from the shape, STL output.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>

#include "body_mesh.hpp"

using namespace hauler;

namespace {

Point normal(const BodyMesh& m, const std::array<int, 3>& t) {
  const auto& a = m.vertices[t[0]];
  const auto& b = m.vertices[t[1]];
  const auto& c = m.vertices[t[2]];
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  return {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
}

}  // namespace

TEST(hauler_mesh, DefaultsAreA24CubicMetreBody) {
  const BodyShape s;
  EXPECT_GE(s.length, 5.5);
  EXPECT_LE(s.length, 6.0);
  EXPECT_GE(s.width, 2.9);
  EXPECT_LE(s.width, 3.3);
  EXPECT_GE(s.side_height, 1.5);
  EXPECT_LE(s.side_height, 1.8);
  EXPECT_NEAR(s.volume(), 24.75, 1e-12);
  const auto m = make_body_mesh(s);
  std::printf("default mesh: %zu triangles, %zu vertices\n", m.triangles.size(), m.vertices.size());
  EXPECT_EQ(m.triangles.size(), 2u * (m.nx * m.ny + m.nz * m.ny + 2 * m.nx * m.nz));
  EXPECT_THROW(make_body_mesh(s, 0.001), std::invalid_argument);
}

// Every edge is shared by at most two triangles and then traversed in opposite directions
// (orientable, consistently oriented, the seams closed); the edges used once are exactly the
// rim: the walls' top edges and the tail edges of the floor and the side walls.
TEST(hauler_mesh, ClosedSeamsOpenTailAndTop) {
  for (double h : {0.2, 0.5}) {
    const BodyShape s;
    const auto m = make_body_mesh(s, h);
    std::map<std::pair<int, int>, int> directed;
    for (const auto& t : m.triangles) {
      const Point n = normal(m, t);
      EXPECT_GT(std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1e-9);
      for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
    }
    int rim = 0, rim_top = 0, rim_tail = 0;
    const double top = s.floor_z + s.side_height;
    for (const auto& [e, n] : directed) {
      ASSERT_EQ(n, 1) << "edge " << e.first << "-" << e.second << " used twice in one direction";
      if (directed.count({e.second, e.first})) continue;
      ++rim;
      const auto& a = m.vertices[e.first];
      const auto& b = m.vertices[e.second];
      if (a[2] == top && b[2] == top) ++rim_top;
      else if (a[0] == s.tail_x && b[0] == s.tail_x) ++rim_tail;
    }
    EXPECT_EQ(rim, 2 * m.nx + m.ny + m.ny + 2 * m.nz) << h;
    EXPECT_EQ(rim_top, 2 * m.nx + m.ny) << h;
    EXPECT_EQ(rim_tail, m.ny + 2 * m.nz) << h;
    std::vector<int> used(m.vertices.size(), 0);
    for (const auto& t : m.triangles)
      for (int v : t) used[v] = 1;
    EXPECT_EQ(std::count(used.begin(), used.end(), 0), 0);
    // one shared vertex per seam point: (nx+1)(ny+1) floor + front, sides without the seams
    const std::size_t expected = (m.nx + 1) * (m.ny + 1) + m.nz * (m.ny + 1) + 2 * m.nx * m.nz;
    EXPECT_EQ(m.vertices.size(), expected);
  }
}

TEST(hauler_mesh, NormalsPointIntoTheLoad) {
  const BodyShape s;
  const auto m = make_body_mesh(s);
  int floor = 0, front = 0, left = 0, right = 0;
  for (const auto& t : m.triangles) {
    auto all = [&](int axis, double v) {
      for (int k : t)
        if (m.vertices[k][axis] != v) return false;
      return true;
    };
    const Point n = normal(m, t);
    if (all(2, s.floor_z)) { EXPECT_GT(n[2], 0); ++floor; }
    else if (all(0, s.front_x())) { EXPECT_LT(n[0], 0); ++front; }
    else if (all(1, 0.5 * s.width)) { EXPECT_LT(n[1], 0); ++left; }
    else if (all(1, -0.5 * s.width)) { EXPECT_GT(n[1], 0); ++right; }
    else ADD_FAILURE() << "a triangle off the four plates";
  }
  EXPECT_EQ(floor, 2 * m.nx * m.ny);
  EXPECT_EQ(front, 2 * m.nz * m.ny);
  EXPECT_EQ(left, 2 * m.nx * m.nz);
  EXPECT_EQ(right, left);
}

// Divergence theorem over the cavity: the mesh (normals into the cavity, so the cavity's
// outward normal is their opposite) plus the open top and tail as analytic faces:
//   V = -sum a.(b x c)/6 + (top face: z_top L W)/3 + (tail face, outward -x: -tail_x W H)/3
// equals the box L W H only if the seams close and every triangle faces into the load.
TEST(hauler_mesh, CavityVolumeEqualsTheBox) {
  for (const BodyShape& s : {BodyShape{}, BodyShape{-0.7, 0.1, 5.9, 3.2, 1.75}}) {
    const auto m = make_body_mesh(s, 0.25);
    double six_v = 0;
    for (const auto& t : m.triangles) {
      const auto& a = m.vertices[t[0]];
      const auto& b = m.vertices[t[1]];
      const auto& c = m.vertices[t[2]];
      six_v += a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) +
               a[2] * (b[0] * c[1] - b[1] * c[0]);
    }
    const double top = (s.floor_z + s.side_height) * s.length * s.width / 3;
    const double tail = -s.tail_x * s.width * s.side_height / 3;
    const double V = -six_v / 6 + top + tail;
    const double box = s.length * s.width * s.side_height;
    std::printf("cavity %.9f m3, box %.9f m3\n", V, box);
    EXPECT_NEAR(V, box, 1e-9 * box);
    EXPECT_EQ(m.volume, box);
  }
}

TEST(hauler_mesh, BoundingBoxFollowsTheShape) {
  const BodyShape s{-0.7, 0.1, 5.9, 3.2, 1.75};
  const auto m = make_body_mesh(s);
  double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9};
  for (const auto& v : m.vertices)
    for (int i = 0; i < 3; ++i) lo[i] = std::min(lo[i], v[i]), hi[i] = std::max(hi[i], v[i]);
  EXPECT_EQ(lo[0], -0.7);
  EXPECT_EQ(hi[0], -0.7 + 5.9);
  EXPECT_EQ(lo[1], -1.6);
  EXPECT_EQ(hi[1], 1.6);
  EXPECT_EQ(lo[2], 0.1);
  EXPECT_EQ(hi[2], 0.1 + 1.75);
}

TEST(hauler_mesh, WritesBinaryStl) {
  const auto m = make_body_mesh(BodyShape{});
  const std::string path = std::string(TEST_TMP_DIR) + "/hauler_body_test.stl";
  write_stl(m, path);
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  ASSERT_TRUE(in);
  EXPECT_EQ(static_cast<std::size_t>(in.tellg()), 84 + 50 * m.triangles.size());
  in.seekg(80);
  std::uint32_t n = 0;
  in.read(reinterpret_cast<char*>(&n), 4);
  EXPECT_EQ(n, m.triangles.size());
  float f[12];
  in.read(reinterpret_cast<char*>(f), sizeof f);
  EXPECT_FLOAT_EQ(f[2], 1.0f);  // the first triangle is on the floor: normal up
  EXPECT_THROW(write_stl(m, "/nonexistent-dir/x.stl"), std::runtime_error);
}
