// The broad phase (every n steps, skin tau r_max) plus the narrow phase finds exactly the
// contacts a brute-force search finds; the guard rebuilds early or, in strict mode, throws.
#include <gtest/gtest.h>

#include <random>
#include <set>
#include <tuple>

#include "dem/mesh_contact.hpp"
#include "dem_test_util.hpp"

namespace {

using namespace demtest;
using dem::State;

constexpr double kRmin = 0.5e-3, kRmax = 1.5e-3;

// Random polydisperse particles in a box with random velocities, a plate tool (a folded
// sheet, so edges are shared) sweeping through them.
std::pair<dem::Scene, State> random_scene(int n_interval, double skin, unsigned seed,
                                          double speed) {
  dem::Scene scene = one_species_scene(kRmin, kRmax);
  scene.broad_phase_interval = n_interval;
  scene.skin = skin;
  scene.threads = 2;
  scene.min_particles_per_thread = 1;
  scene.particle_particle = scene.particle_wall = law_n_per_m(50, 0.5, true, 0.3);
  const double L = 0.02;
  scene.walls = {{"x0", {0, 0, 0}, {1, 0, 0}}, {"x1", {L, 0, 0}, {-1, 0, 0}},
                 {"y0", {0, 0, 0}, {0, 1, 0}}, {"y1", {0, L, 0}, {0, -1, 0}},
                 {"z0", {0, 0, 0}, {0, 0, 1}}, {"z1", {0, 0, L}, {0, 0, -1}}};
  std::vector<Vec3> c;
  const double w = 0.006;
  quad(c, {-w, -w, 0}, {0, -w, 0.3 * w}, {0, w, 0.3 * w}, {-w, w, 0});
  quad(c, {0, -w, 0.3 * w}, {w, -w, 0}, {w, w, 0}, {0, w, 0.3 * w});
  dem::Tool tool = static_tool("plate", c);
  tool.motion.keyframes = {{0, {0.004, 0.01, 0.002}, {1, 0, 0, 0}},
                           {0.02, {0.016, 0.01, 0.018}, {0.9238795, 0.3826834, 0, 0}}};
  scene.tools.push_back(tool);
  State st;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  const double h = 2 * kRmax * 1.05;
  for (int iz = 0; iz < 6; ++iz)
    for (int iy = 0; iy < 6; ++iy)
      for (int ix = 0; ix < 6; ++ix) {
        if (U(rng) < 0.15) continue;
        const double r = kRmin + (kRmax - kRmin) * U(rng);
        const Vec3 x{kRmax + ix * h + 0.2e-3 * U(rng), kRmax + iy * h + 0.2e-3 * U(rng),
                     kRmax + iz * h + 0.2e-3 * U(rng)};
        add(st, x, {speed * (2 * U(rng) - 1), speed * (2 * U(rng) - 1), speed * (2 * U(rng) - 1)},
            r);
      }
  scene.dt = 2e-5;
  st.tool_pose = {tool.motion.evaluate(0)};
  return {scene, st};
}

std::vector<std::pair<std::int64_t, std::int64_t>> brute_pairs(const State& s) {
  std::vector<std::pair<std::int64_t, std::int64_t>> out;
  for (std::size_t i = 0; i < s.size(); ++i)
    for (std::size_t j = i + 1; j < s.size(); ++j) {
      const double rs = s.radius[i] + s.radius[j];
      if (norm2(s.x[i] - s.x[j]) < rs * rs)
        out.emplace_back(std::min(s.id[i], s.id[j]), std::max(s.id[i], s.id[j]));
    }
  std::sort(out.begin(), out.end());
  return out;
}

std::set<std::tuple<std::int64_t, int, std::uint64_t>> brute_mesh(const dem::Scene& scene,
                                                                   const State& s) {
  std::set<std::tuple<std::int64_t, int, std::uint64_t>> out;
  for (std::size_t m = 0; m < scene.tools.size(); ++m) {
    const dem::Mesh& mesh = scene.tools[m].mesh;
    const dem::ToolPose& p = s.tool_pose[m];
    const dem::Mat3 R = dem::to_matrix(p.orientation);
    std::vector<Vec3> wv;
    for (const Vec3& v : mesh.vertices) wv.push_back(p.position + R * v);
    for (std::size_t i = 0; i < s.size(); ++i) {
      std::vector<dem::TriangleHit> hits;
      for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        const auto h = dem::closest_on_triangle(mesh, wv.data(), static_cast<int>(t), s.x[i]);
        if (h.dist2 < s.radius[i] * s.radius[i]) hits.push_back(h);
      }
      const int n = dem::select_mesh_contacts(mesh, hits.data(), static_cast<int>(hits.size()));
      for (int k = 0; k < n; ++k)
        out.emplace(s.id[i], static_cast<int>(m),
                    dem::contact_key(hits[k].kind, static_cast<std::uint32_t>(m),
                                     static_cast<std::uint32_t>(hits[k].feature)));
    }
  }
  return out;
}

TEST(dem_BroadPhase, MatchesBruteForceForSeveralIntervalsAndSkins) {
  for (int n : {1, 5, 20})
    for (double skin : {0.1, 0.4, 1.0}) {
      auto [scene, st] = random_scene(n, skin, 11 + n, 0.3);
      dem::Engine engine(scene);
      std::size_t pair_contacts = 0, mesh_contacts = 0;
      for (int k = 0; k < 600; ++k) {
        st.tool_pose[0] = scene.tools[0].motion.evaluate(st.step * scene.dt);
        engine.prepare(st);
        if (k % 7 == 0) {  // the brute force is O(N^2): sample every 7th step
          const auto want = brute_pairs(st);
          ASSERT_EQ(engine.particle_contacts(st), want) << "n " << n << " skin " << skin
                                                        << " step " << k;
          pair_contacts += want.size();
          const auto want_mesh = brute_mesh(scene, st);
          std::set<std::tuple<std::int64_t, int, std::uint64_t>> got;
          for (const auto& c : engine.mesh_contacts(st)) got.emplace(c.particle, c.tool, c.key);
          ASSERT_EQ(got, want_mesh) << "n " << n << " skin " << skin << " step " << k;
          mesh_contacts += want_mesh.size();
        }
        engine.step(st);
      }
      std::printf("n %2d skin %.1f: %zu pair and %zu mesh contacts checked, %lld rebuilds "
                  "(%lld early)\n",
                  n, skin, pair_contacts, mesh_contacts, static_cast<long long>(st.rebuilds),
                  static_cast<long long>(st.early_rebuilds));
      EXPECT_GT(pair_contacts, 100u);  // the comparison is not vacuous
      EXPECT_GT(mesh_contacts, 20u);
    }
}

TEST(dem_BroadPhase, GuardRebuildsEarlyWhenIntervalIsTooLong) {
  auto [scene, st] = random_scene(1000, 0.1, 3, 1.0);
  dem::Engine engine(scene);
  for (int k = 0; k < 400; ++k) {
    st.tool_pose[0] = scene.tools[0].motion.evaluate(st.step * scene.dt);
    engine.prepare(st);
    if (k % 10 == 0) {
      ASSERT_EQ(engine.particle_contacts(st), brute_pairs(st)) << k;
    }
    engine.step(st);
  }
  EXPECT_GT(st.early_rebuilds, 5);
  EXPECT_EQ(st.rebuilds, st.early_rebuilds + 1);  // only the first one was due
}

TEST(dem_BroadPhase, StrictGuardThrowsNamingIntervalAndSkin) {
  auto [scene, st] = random_scene(1000, 0.1, 3, 1.0);
  scene.guard = dem::GuardMode::strict;
  dem::Engine engine(scene);
  try {
    for (int k = 0; k < 400; ++k) engine.step(st);
    FAIL() << "strict guard never fired";
  } catch (const dem::SimulationError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("scene.broad_phase_interval (now 1000)"), std::string::npos) << msg;
    EXPECT_NE(msg.find("scene.skin (now 0.1)"), std::string::npos) << msg;
  }
}

}  // namespace
