// The bucket mesh: triangle counts, a consistently oriented manifold shell with the rim we
// expect, normals on the soil side, bounding box and capacity from the shape, STL output.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <map>

#include "bucket_mesh.hpp"

using namespace wheel_loader;

namespace {

std::array<double, 3> normal(const BucketMesh& m, const std::array<int, 3>& t) {
  const auto& a = m.vertices[t[0]];
  const auto& b = m.vertices[t[1]];
  const auto& c = m.vertices[t[2]];
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  return {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
}

}  // namespace

TEST(wheel_loader_mesh, TriangleCountsDefaultAndFinest) {
  const BucketShape s;
  const auto coarse = make_bucket_mesh(s, 1);
  const auto fine = make_bucket_mesh(s, kMaxRefine);
  std::printf("triangles: refine 1 %zu, refine %d %zu\n", coarse.triangles.size(), kMaxRefine,
              fine.triangles.size());
  EXPECT_GE(coarse.triangles.size(), 2000u);
  EXPECT_LE(coarse.triangles.size(), 5000u);
  EXPECT_GE(fine.triangles.size(), 36000u);
  EXPECT_LE(fine.triangles.size(), 44000u);
  EXPECT_THROW(make_bucket_mesh(s, kMaxRefine + 1), std::invalid_argument);
}

// Every edge is shared by at most two triangles, and then traversed in opposite directions
// (orientable, consistently oriented); the edges used once form exactly the rim.
TEST(wheel_loader_mesh, ConsistentlyOrientedShellWithTheExpectedRim) {
  for (int refine : {1, 2}) {
    const BucketShape s;
    const auto m = make_bucket_mesh(s, refine);
    std::map<std::pair<int, int>, int> directed;
    for (const auto& t : m.triangles) {
      EXPECT_GT(std::sqrt([&] { auto n = normal(m, t); return n[0] * n[0] + n[1] * n[1] + n[2] * n[2]; }()), 1e-12);
      for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
    }
    int rim = 0;
    for (const auto& [e, n] : directed) {
      ASSERT_EQ(n, 1) << "edge " << e.first << "-" << e.second << " used twice in one direction";
      if (!directed.count({e.second, e.first})) ++rim;
    }
    // rim: spill-guard top and bevel back edge (width pieces each), the side plates' front
    // edges and the bevel ends; count them from the geometry
    const double h = 0.1 / refine;
    auto pieces = [&](double len) { return std::max(1, int(std::ceil(len / h - 1e-9))); };
    const int nw = pieces(s.width);
    const int n_bevel = pieces(std::hypot(s.edge_depth, s.edge_thickness));
    const double a = s.guard_angle * M_PI / 180;
    const double gx = s.back_x + s.guard_length * std::cos(a), gz = s.back_top_z + s.guard_length * std::sin(a);
    const int n_front = pieces(std::hypot(gx - s.edge_x, gz - s.floor_z));
    EXPECT_EQ(rim, 2 * nw + 2 * n_bevel + 2 * n_front) << "refine " << refine;
    // every vertex is used
    std::vector<int> used(m.vertices.size(), 0);
    for (const auto& t : m.triangles)
      for (int v : t) used[v] = 1;
    EXPECT_EQ(std::count(used.begin(), used.end(), 0), 0);
  }
}

TEST(wheel_loader_mesh, NormalsOnTheSoilSide) {
  const BucketShape s;
  const auto m = make_bucket_mesh(s, 1);
  int floor = 0, back = 0, left = 0, right = 0;
  for (const auto& t : m.triangles) {
    auto all = [&](int axis, double v) {
      for (int k : t)
        if (std::abs(m.vertices[k][axis] - v) > 1e-12) return false;
      return true;
    };
    const auto n = normal(m, t);
    if (all(2, s.floor_z)) { EXPECT_GT(n[2], 0); ++floor; }        // bottom plate: up
    if (all(0, s.back_x)) { EXPECT_GT(n[0], 0); ++back; }          // back plate: forward
    if (all(1, 0.5 * s.width)) { EXPECT_LT(n[1], 0); ++left; }     // side plates: inward
    if (all(1, -0.5 * s.width)) { EXPECT_GT(n[1], 0); ++right; }
  }
  EXPECT_GT(floor, 100);
  EXPECT_GT(back, 100);
  EXPECT_GT(left, 100);
  EXPECT_EQ(left, right);
}

TEST(wheel_loader_mesh, BoundingBoxAndCapacityFollowTheShape) {
  BucketShape s;
  s.width = 2.7;
  const auto m = make_bucket_mesh(s, 1);
  double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9};
  for (const auto& v : m.vertices)
    for (int i = 0; i < 3; ++i) lo[i] = std::min(lo[i], v[i]), hi[i] = std::max(hi[i], v[i]);
  const double a = s.guard_angle * M_PI / 180;
  EXPECT_NEAR(lo[0], s.back_x, 1e-12);
  EXPECT_NEAR(hi[0], s.edge_x, 1e-12);
  EXPECT_NEAR(lo[1], -1.35, 1e-12);
  EXPECT_NEAR(hi[1], 1.35, 1e-12);
  EXPECT_NEAR(lo[2], s.floor_z - s.edge_thickness, 1e-12);
  EXPECT_NEAR(hi[2], s.back_top_z + s.guard_length * std::sin(a), 1e-12);
  // the default is a 4.4 m3 (heaped) class bucket; capacity scales with the width
  const auto d = make_bucket_mesh(BucketShape{}, 1);
  std::printf("capacity: struck %.3f m3, heaped %.3f m3\n", d.struck_volume, d.heaped_volume);
  EXPECT_GT(d.heaped_volume, 4.0);
  EXPECT_LT(d.heaped_volume, 5.0);
  EXPECT_NEAR(m.struck_volume / d.struck_volume, 2.7 / 3.0, 1e-12);
  // polygon area converges to the exact one (the heel arc's chords cut a little off)
  const double exact_area = [&] {
    const BucketShape& b = s;
    const double R = b.heel_radius;
    const double gx = b.back_x + b.guard_length * std::cos(a), gz = b.back_top_z + b.guard_length * std::sin(a);
    // polygon E, (back_x, floor_z) corner, (back_x, back_top_z), G, minus the heel's corner
    const double px[4] = {b.edge_x, b.back_x, b.back_x, gx}, pz[4] = {b.floor_z, b.floor_z, b.back_top_z, gz};
    double A = 0;
    for (int i = 0; i < 4; ++i) A += px[i] * pz[(i + 1) % 4] - px[(i + 1) % 4] * pz[i];
    return 0.5 * std::abs(A) - R * R * (1 - M_PI / 4);
  }();
  const auto f = make_bucket_mesh(s, kMaxRefine);
  EXPECT_NEAR(f.struck_volume / s.width, exact_area, 2e-4 * exact_area);
}

TEST(wheel_loader_mesh, WritesBinaryStl) {
  const auto m = make_bucket_mesh(BucketShape{}, 1);
  const std::string path = std::string(TEST_TMP_DIR) + "/bucket_test.stl";
  write_stl(m, path);
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  ASSERT_TRUE(in);
  const auto size = static_cast<std::size_t>(in.tellg());
  EXPECT_EQ(size, 84 + 50 * m.triangles.size());
  in.seekg(80);
  std::uint32_t n = 0;
  in.read(reinterpret_cast<char*>(&n), 4);
  EXPECT_EQ(n, m.triangles.size());
  float f[12];
  in.read(reinterpret_cast<char*>(f), sizeof f);
  const auto& v0 = m.vertices[m.triangles[0][0]];
  EXPECT_FLOAT_EQ(f[3], static_cast<float>(v0[0]));
  EXPECT_NEAR(f[0] * f[0] + f[1] * f[1] + f[2] * f[2], 1.0, 1e-6);
  EXPECT_THROW(write_stl(m, "/nonexistent-dir/x.stl"), std::runtime_error);
}
