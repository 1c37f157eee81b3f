// A sphere translated across a folded mesh (a roof ridge, a vertex fan) feels one contact
// with the force of the true distance to the surface: continuous, never double counted.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "dem/mesh_contact.hpp"
#include "dem_test_util.hpp"

namespace {

using namespace demtest;
using dem::State;

constexpr double kR = 0.01, kK = 1e4;

// Reference distance from p to a triangle, computed differently from the engine: project on
// the plane and test the barycentric signs; otherwise the nearest of the three segments.
double ref_distance(Vec3 p, Vec3 a, Vec3 b, Vec3 c) {
  const Vec3 n0 = cross(b - a, c - a);
  const Vec3 n = (1.0 / norm(n0)) * n0;
  const Vec3 q = p - dot(p - a, n) * n;
  const double s0 = dot(cross(b - a, q - a), n), s1 = dot(cross(c - b, q - b), n),
               s2 = dot(cross(a - c, q - c), n);
  if (s0 >= 0 && s1 >= 0 && s2 >= 0) return std::abs(dot(p - a, n));
  auto seg = [&](Vec3 u, Vec3 w) {
    const double t = std::clamp(dot(p - u, w - u) / norm2(w - u), 0.0, 1.0);
    return norm(p - (u + t * (w - u)));
  };
  return std::min({seg(a, b), seg(b, c), seg(c, a)});
}

struct Sweep {
  double max_rel_error = 0;  // | |F| - k (r - d_ref) | / (k r)
  double max_jump = 0;       // largest step-to-step change of F, relative to k * step length
  int max_contacts = 0;
};

// Moves the sphere along `path(s)`, s in [0, 1], resetting its position and velocity every step.
// Reference force: convex folds touch the nearest point only; a concave valley touches each
// flat side (triangles 0-1 and 2-3) once.
Sweep sweep(const std::vector<Vec3>& corners, const std::function<Vec3(double)>& path, double mu,
            bool per_side = false) {
  dem::Scene scene = one_species_scene(kR, kR);
  dem::ContactLaw law = law_n_per_m(kK, 0.5, true, mu, 1.0, 0.0);
  law.damping_from_restitution = false;  // elastic: |F| must be exactly k * overlap
  law.normal_damping = 0;
  scene.particle_particle = scene.particle_wall = law;
  scene.tools.push_back(static_tool("fold", corners));
  const int steps = 2000;
  const double T = 0.2;
  scene.dt = T / steps;
  State st;
  add(st, path(0), {}, kR);
  st.tool_pose.resize(1);
  dem::Engine engine(scene);
  Sweep out;
  Vec3 f_prev;
  for (int k = 0; k <= steps; ++k) {
    const double s = static_cast<double>(k) / steps;
    const Vec3 x = path(s);
    const Vec3 v = (1.0 / T) * (path(std::min(1.0, s + 1e-6)) - path(s)) * 1e6;
    st.x[0] = x;
    st.v[0] = st.u[0] = v;
    engine.step(st);
    const Vec3 f = -engine.tool_wrenches()[0].force;  // on the sphere
    auto dist = [&](std::size_t t0, std::size_t t1) {
      double d = 1e300;
      for (std::size_t c = 3 * t0; c < 3 * t1; c += 3)
        d = std::min(d, ref_distance(x, corners[c], corners[c + 1], corners[c + 2]));
      return d;
    };
    double want;
    if (per_side) {
      // Each side is planar: its force points along its normal.
      auto side = [&](std::size_t t0) {
        const Vec3 a = corners[3 * t0], b = corners[3 * t0 + 1], c = corners[3 * t0 + 2];
        Vec3 n = cross(b - a, c - a);
        n = (1.0 / norm(n)) * n;
        if (dot(x - a, n) < 0) n = -n;
        return kK * std::max(0.0, kR - dist(t0, t0 + 2)) * n;
      };
      want = norm(side(0) + side(2));
    } else {
      want = kK * std::max(0.0, kR - dist(0, corners.size() / 3));
    }
    if (mu == 0) out.max_rel_error = std::max(out.max_rel_error, std::abs(norm(f) - want) / (kK * kR));
    if (k > 0) {
      const double step_len = norm(x - path(static_cast<double>(k - 1) / steps));
      out.max_jump = std::max(out.max_jump, norm(f - f_prev) / (kK * step_len));
    }
    f_prev = f;
    out.max_contacts = std::max(out.max_contacts, static_cast<int>(engine.mesh_contacts(st).size()));
  }
  return out;
}

std::vector<Vec3> roof(double slope_deg) {
  const double L = 0.05, dz = -L * std::tan(slope_deg * M_PI / 180);
  std::vector<Vec3> c;
  quad(c, {0, -L, 0}, {0, L, 0}, {-L, L, dz}, {-L, -L, dz});
  quad(c, {0, -L, 0}, {L, -L, dz}, {L, L, dz}, {0, L, 0});
  return c;
}

std::vector<Vec3> fan(double slope_deg, int sides) {
  const double L = 0.05, dz = -L * std::tan(slope_deg * M_PI / 180);
  std::vector<Vec3> c;
  for (int k = 0; k < sides; ++k) {
    const double a0 = 2 * M_PI * k / sides, a1 = 2 * M_PI * (k + 1) / sides;
    c.insert(c.end(), {Vec3{0, 0, 0}, Vec3{L * std::cos(a0), L * std::sin(a0), dz},
                       Vec3{L * std::cos(a1), L * std::sin(a1), dz}});
  }
  return c;
}

TEST(dem_MeshContact, RidgeAndVertexFanGiveOneContinuousContact) {
  const double h = 0.8 * kR;  // centre height above the ridge/apex: 20 % overlap there
  struct Case {
    const char* name;
    std::vector<Vec3> mesh;
    std::function<Vec3(double)> path;
  };
  std::vector<Case> cases = {
      {"convex ridge", roof(10), [&](double s) { return Vec3{-0.02 + 0.04 * s, 0.003, h}; }},
      {"concave valley", roof(-10),
       [&](double s) { return Vec3{-0.02 + 0.04 * s, 0.003, h + 0.002}; }},
      {"vertex fan (over apex)", fan(10, 6),
       [&](double s) { return Vec3{-0.02 + 0.04 * s, 0, h}; }},
      {"vertex fan (off apex)", fan(10, 7),
       [&](double s) { return Vec3{-0.02 + 0.04 * s, 0.001 + 0.002 * s, h}; }},
  };
  for (const Case& c : cases) {
    const bool valley = std::string(c.name) == "concave valley";
    const Sweep r = sweep(c.mesh, c.path, 0.0, valley);
    std::printf("%-24s frictionless: max |F| error %.2e k r, max jump %.3f k dx, contacts <= %d\n",
                c.name, r.max_rel_error, r.max_jump, r.max_contacts);
    // A double count would be off by the whole overlap (~20 % of k r); what remains is the
    // force window where the contact starts or ends (docs/physics.md).
    EXPECT_LT(r.max_rel_error, 1e-4) << c.name;
    EXPECT_LT(r.max_jump, 1.0 + 1e-6) << c.name;  // |dF| <= k |dx|: no jump
    const Sweep rf = sweep(c.mesh, c.path, 0.5, valley);
    std::printf("%-24s mu = 0.5:     max jump %.3f k dx\n", c.name, rf.max_jump);
    // With friction the force turns with the normal but may not jump.
    EXPECT_LT(rf.max_jump, 2.0) << c.name;
  }
}

TEST(dem_MeshContact, ClosestFeatureClassification) {
  const std::vector<Vec3> c = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const dem::Mesh mesh = dem::build_mesh(c, "tri");
  const Vec3* wv = mesh.vertices.data();
  auto kind = [&](Vec3 p) { return dem::closest_on_triangle(mesh, wv, 0, p).kind; };
  EXPECT_EQ(kind({0.2, 0.2, 1}), dem::FeatureKind::face);
  EXPECT_EQ(kind({0.5, -0.3, 1}), dem::FeatureKind::edge);
  EXPECT_EQ(kind({0.8, 0.8, 0.1}), dem::FeatureKind::edge);
  EXPECT_EQ(kind({-0.1, -0.1, 0}), dem::FeatureKind::vertex);
  EXPECT_EQ(kind({1.5, -0.1, 0}), dem::FeatureKind::vertex);
  EXPECT_NEAR(dem::closest_on_triangle(mesh, wv, 0, {0.8, 0.8, 0}).dist2, 2 * 0.3 * 0.3, 1e-15);
}

// triangles_within (4 triangles at a time in lanes where the processor has AVX2) decides as
// closest_on_triangle(...).dist2 < reach2 does, bit for bit: on a crumpled sheet of 8 x 8 quads
// (random heights, triangles of every shape and orientation, each edge with its lower vertex
// first in the mesh) against points around a triangle and its neighbours (every region: the
// face, each edge, each vertex), for groups of 1 to 4 triangles, with reach2 set
// exactly to one triangle's squared distance (below is false), one ulp above it (true) and
// random. A one-ulp difference in any region's distance flips a decision.
TEST(dem_MeshContact, TrianglesWithinDecideAsTheClosestPoint) {
  std::mt19937_64 rng(2026);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  constexpr int kN = 8;
  double height[kN + 1][kN + 1];
  for (auto& row : height)
    for (double& h : row) h = 0.3 * u01(rng);
  std::vector<Vec3> corners;
  for (int i = 0; i < kN; ++i)
    for (int j = 0; j < kN; ++j) {
      const double x0 = i, x1 = i + 1, y0 = j, y1 = j + 1;
      const Vec3 p00{x0, y0, height[i][j]}, p10{x1, y0, height[i + 1][j]},
          p01{x0, y1, height[i][j + 1]}, p11{x1, y1, height[i + 1][j + 1]};
      const bool flip = (i + j) % 3 == 0;  // diagonals both ways, and triangles turned about
      for (const Vec3& q : flip ? std::vector<Vec3>{p00, p10, p11, p00, p11, p01}
                                : std::vector<Vec3>{p10, p01, p00, p11, p01, p10})
        corners.push_back(q);
    }
  const dem::Mesh mesh = dem::build_mesh(corners, "crumpled sheet");
  const Vec3* wv = mesh.vertices.data();
  const int nt = static_cast<int>(mesh.triangles.size());
  std::uniform_int_distribution<int> pick(0, nt - 1), count(1, 4);
  int kinds[4] = {0, 0, 0, 0}, hits = 0, misses = 0, groups = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const int n = count(rng);
    std::int32_t tri[4];
    // Mostly neighbours (a sphere's candidates), sometimes the same triangle twice.
    const int t0 = pick(rng);
    for (int l = 0; l < n; ++l)
      tri[l] = u01(rng) < 0.2 ? t0
                              : std::clamp(t0 + static_cast<int>(u01(rng) * 5) - 2, 0, nt - 1);
    // A point around t0: barycentric coordinates from -0.4 to 1.2, up to half a side off.
    const auto& T = mesh.triangles[static_cast<std::size_t>(t0)];
    const double b1 = -0.4 + 1.6 * u01(rng), b2 = -0.4 + 1.6 * u01(rng);
    const Vec3 c = (1 - b1 - b2) * wv[T[0]] + b1 * wv[T[1]] + b2 * wv[T[2]] +
                   Vec3{0, 0, -0.5 + u01(rng)};
    double d2[4];
    for (int l = 0; l < n; ++l) {
      const dem::TriangleHit h = dem::closest_on_triangle(mesh, wv, tri[l], c);
      d2[l] = h.dist2;
      ++kinds[static_cast<int>(h.kind)];
    }
    const int at = static_cast<int>(u01(rng) * n);
    for (const double reach2 : {d2[at], std::nextafter(d2[at], 1e300), 0.5 * u01(rng)}) {
      int expected = 0;
      for (int l = 0; l < n; ++l) expected |= (d2[l] < reach2) << l;
      ASSERT_EQ(dem::triangles_within(mesh, wv, tri, n, c, reach2), expected)
          << "trial " << trial << ", " << n << " triangles, reach2 " << reach2;
      hits += __builtin_popcount(static_cast<unsigned>(expected));
      misses += n - __builtin_popcount(static_cast<unsigned>(expected));
      ++groups;
    }
  }
  std::printf("%d groups (lanes %s): %d within, %d not; closest features: %d faces, %d edges, "
              "%d vertices\n",
              groups, dem::triangles_within_lanes_available() ? "AVX2" : "absent", hits, misses,
              kinds[1], kinds[2], kinds[3]);
  EXPECT_GT(kinds[static_cast<int>(dem::FeatureKind::face)], 5000);
  EXPECT_GT(kinds[static_cast<int>(dem::FeatureKind::edge)], 5000);
  EXPECT_GT(kinds[static_cast<int>(dem::FeatureKind::vertex)], 5000);
}

}  // namespace
