// The broad phase (every n steps, skin tau r_max) plus the narrow phase finds exactly the
// contacts a brute-force search finds; the guard rebuilds early or, in strict mode, throws.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <memory>
#include <random>
#include <set>
#include <tuple>

#include "dem/checkpoint.hpp"
#include "dem/mesh_contact.hpp"
#include "dem_test_util.hpp"

namespace {

using namespace demtest;
using dem::State;

constexpr double kRmin = 0.5e-3, kRmax = 1.5e-3;

// The scenes below use every thread they ask for, however few their particles.
const dem::EngineOptions kEveryThread = [] {
  dem::EngineOptions o;
  o.min_particles_per_thread = 1;
  return o;
}();

// Random polydisperse particles in a box with random velocities, a plate tool (a folded
// sheet, so edges are shared) sweeping through them.
std::pair<dem::Scene, State> random_scene(int n_interval, double skin, unsigned seed,
                                          double speed) {
  dem::Scene scene = one_species_scene(kRmin, kRmax);
  scene.broad_phase_interval = n_interval;
  scene.skin = skin;
  scene.threads = 2;
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

// Steps st `steps` times with the tool on its motion. At step `checkpoint_at` (-1: never) the
// state goes through a checkpoint file (named from `tag`) and a new engine takes over;
// done(engine) is called for each engine when it is dropped (at the checkpoint and at the end).
template <class Done>
void run_with_tool(const dem::Scene& scene, const dem::EngineOptions& options, State& st,
                   int steps, int checkpoint_at, const std::string& tag, Done&& done) {
  auto engine = std::make_unique<dem::Engine>(scene, options);
  for (int k = 0; k < steps; ++k) {
    if (k == checkpoint_at) {
      done(*engine);
      const std::string file = (std::filesystem::temp_directory_path() /
                                (tag + std::to_string(::getpid()) + ".h5"))
                                   .string();
      dem::save_checkpoint(st, file);
      st = dem::load_checkpoint(file);
      std::filesystem::remove(file);
      engine = std::make_unique<dem::Engine>(scene, options);
    }
    st.tool_pose[0] = scene.tools[0].motion.evaluate(st.step * scene.dt);
    engine->step(st);
  }
  done(*engine);
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
      dem::Engine engine(scene, kEveryThread);
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
  dem::Engine engine(scene, kEveryThread);
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

// A folded sheet of triangles much smaller than the spheres (a fine tool mesh: edges a quarter of
// a radius), turned and shifted, with spheres at random heights from 0.3 r to 1.2 r over it: the
// contacts through the candidate lists and the triangles' bounding-sphere test equal a brute-force
// search over every triangle. A bound that dropped a triangle within the reach would miss the
// contacts near their edge.
TEST(dem_BroadPhase, FineMeshContactsMatchBruteForce) {
  const double r = 0.5e-3;
  dem::Scene scene = one_species_scene(r, r);
  scene.particle_particle = scene.particle_wall = law_n_per_m(50, 0.5, true, 0.3);
  scene.skin = 0.4;
  std::vector<Vec3> c;
  const int cells = 48;
  const double w = 0.006, h = w / cells;  // 0.125 mm squares: edges of a quarter radius
  for (int side = 0; side < 2; ++side)
    for (int a = 0; a < cells; ++a)
      for (int b = 0; b < 2 * cells; ++b) {
        auto at = [&](int u, int v) {
          const double x = side == 0 ? -w + u * h : u * h;
          const double z = side == 0 ? 0.3 * (x + w) : 0.3 * (w - x);
          return Vec3{x, -w + v * h, z * 0.5};
        };
        quad(c, at(a, b), at(a + 1, b), at(a + 1, b + 1), at(a, b + 1));
      }
  dem::Tool tool = static_tool("fine", c);
  tool.motion.keyframes = {{0, {0.01, 0.01, 0.002}, {0.9238795, 0.3826834, 0, 0}}};
  scene.tools.push_back(tool);
  State st;
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> U(0, 1);
  const dem::ToolPose pose = tool.motion.evaluate(0);
  const dem::Mat3 R = dem::to_matrix(pose.orientation);
  for (int k = 0; k < 1500; ++k) {
    // A point on the sheet (mesh frame), lifted along the sheet's normal by 0.3-1.2 r.
    const double x = -w + 2 * w * U(rng), y = -w + 2 * w * U(rng);
    const double z = 0.5 * (x < 0 ? 0.3 * (x + w) : 0.3 * (w - x));
    const Vec3 nrm = x < 0 ? Vec3{-0.15, 0, 1} : Vec3{0.15, 0, 1};
    const Vec3 p = Vec3{x, y, z} + ((0.3 + 0.9 * U(rng)) * r / norm(nrm)) * nrm;
    const Vec3 world = pose.position + R * p;
    bool free = true;
    for (std::size_t q = 0; q < st.size() && free; ++q) free = norm2(st.x[q] - world) > 4 * r * r;
    if (free) add(st, world, {}, r);
  }
  st.tool_pose = {pose};
  dem::Engine engine(scene);
  engine.prepare(st);
  const auto want = brute_mesh(scene, st);
  std::set<std::tuple<std::int64_t, int, std::uint64_t>> got;
  for (const auto& m : engine.mesh_contacts(st)) got.emplace(m.particle, m.tool, m.key);
  EXPECT_EQ(got, want);
  std::printf("%zu spheres, %zu triangles, %zu mesh contacts\n", st.size(),
              scene.tools[0].mesh.triangles.size(), want.size());
  EXPECT_GT(want.size(), 50u);  // not vacuous
}

// Fast particles in the box of random_scene, rebuilt only when the guard says so: its bound
// fires at nearly every step once a fast particle moved half the skin, and its far-mover check
// (Engine::far_movers_clear) decides. Four cases, each one part of the check:
//  bed   - a bed at rest in the lower half, fast particles shot down into it (new neighbours
//          found through the grid);
//  walls - fast particles only, flying at the walls;
//  plate - fast particles only, shot at the plate, which stands still;
//  meet  - fast particles only, in pairs flying at each other (two far movers).
enum class FarCase { bed, walls, plate, meet };

std::pair<dem::Scene, State> far_mover_scene(FarCase c, unsigned seed) {
  auto [scene, st] = random_scene(1 << 30, 0.4, seed, 0.0);
  cosim::Keyframe only = scene.tools[0].motion.keyframes.at(0);
  only.position = {0.01, 0.01, 0.006};  // the plate stands still in the middle of the box
  scene.tools[0].motion.keyframes = {only};
  const dem::ToolPose still = scene.tools[0].motion.evaluate(0);
  State out;
  if (c == FarCase::bed)
    for (std::size_t i = 0; i < st.size(); ++i)
      if (st.x[i].z < 0.009) add(out, st.x[i], {}, st.radius[i]);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  auto radius = [&] { return kRmin + (kRmax - kRmin) * U(rng); };
  auto unit = [](Vec3 d) { return (1.0 / norm(d)) * d; };
  for (int k = 0; k < 16; ++k) {
    const double speed = 2.0 + 3.0 * U(rng);  // 4e-5 to 1e-4 m a step: half the skin in 3-8
    switch (c) {
      case FarCase::bed:
        add(out, {0.003 + 0.014 * U(rng), 0.003 + 0.014 * U(rng), 0.012 + 0.006 * U(rng)},
            speed * unit({U(rng) - 0.5, U(rng) - 0.5, -1.0}), radius());
        break;
      case FarCase::walls:
        add(out, {0.005 + 0.01 * U(rng), 0.005 + 0.01 * U(rng), 0.005 + 0.01 * U(rng)},
            speed * unit({U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5}), radius());
        break;
      case FarCase::plate: {  // from above the plate, down onto it
        const Vec3 at = still.position + Vec3{0.008 * (U(rng) - 0.5), 0.008 * (U(rng) - 0.5), 0};
        add(out, at + Vec3{0, 0, 0.004 + 0.004 * U(rng)},
            speed * unit({0.2 * (U(rng) - 0.5), 0.2 * (U(rng) - 0.5), -1.0}), radius());
        break;
      }
      case FarCase::meet: {  // two at a time, 2-6 mm apart, flying at each other
        const Vec3 mid{0.004 + 0.012 * U(rng), 0.004 + 0.012 * U(rng), 0.012 + 0.006 * U(rng)};
        const Vec3 d = unit({U(rng) - 0.5, U(rng) - 0.5, 0.2 * (U(rng) - 0.5)});
        const double half = 0.001 + 0.002 * U(rng);
        add(out, mid + half * d, -speed * d, radius());
        add(out, mid - half * d, speed * d, radius());
        ++k;
        break;
      }
    }
  }
  out.tool_pose = {still};
  return {scene, out};
}

TEST(dem_BroadPhase, FarMoverCheckKeepsEveryContactInTheLists) {
  const char* names[] = {"bed", "walls", "plate", "meet"};
  for (FarCase c : {FarCase::bed, FarCase::walls, FarCase::plate, FarCase::meet}) {
    const char* name = names[static_cast<int>(c)];
    long long cleared = 0, early = 0, pair_contacts = 0, mesh_contacts = 0, wall_contacts = 0;
    for (unsigned seed : {5u, 6u, 7u}) {
      auto [scene, st] = far_mover_scene(c, seed);
      dem::Engine engine(scene, kEveryThread);
      for (int k = 0; k < 400; ++k) {
        engine.prepare(st);
        const auto want = brute_pairs(st);
        ASSERT_EQ(engine.particle_contacts(st), want) << name << " seed " << seed << " step " << k;
        pair_contacts += static_cast<long long>(want.size());
        const auto want_mesh = brute_mesh(scene, st);
        std::set<std::tuple<std::int64_t, int, std::uint64_t>> got;
        for (const auto& m : engine.mesh_contacts(st)) got.emplace(m.particle, m.tool, m.key);
        ASSERT_EQ(got, want_mesh) << name << " seed " << seed << " step " << k;
        mesh_contacts += static_cast<long long>(want_mesh.size());
        for (std::size_t i = 0; i < st.size(); ++i)
          for (std::size_t w = 0; w < scene.walls.size(); ++w)
            if (dot(st.x[i] - scene.walls[w].point, scene.walls[w].normal) < st.radius[i]) {
              ASSERT_TRUE((st.wall_mask[i] >> w) & 1u) << name << ": particle " << st.id[i]
                                                       << " touches wall " << w << " at step " << k;
              ASSERT_GE(st.slot_block[i], 0) << name << " particle " << st.id[i] << " step " << k;
              ++wall_contacts;
            }
        engine.step(st);
      }
      cleared += engine.guard_cleared();
      early += st.early_rebuilds;
    }
    std::printf("%-5s: %lld pair, %lld mesh and %lld wall contacts checked; the far-mover check "
                "spared %lld broad phases, %lld ran early\n",
                name, pair_contacts, mesh_contacts, wall_contacts, cleared, early);
    // Not vacuous: the case's contacts happened, the check let the lists live on, and it still
    // sent for a broad phase when a contact was coming.
    if (c == FarCase::bed || c == FarCase::meet) {
      EXPECT_GT(pair_contacts, 30) << name;
    }
    if (c == FarCase::plate) {
      EXPECT_GT(mesh_contacts, 30) << name;
    }
    if (c == FarCase::walls) {
      EXPECT_GT(wall_contacts, 30) << name;
    }
    EXPECT_GT(cleared, 300) << name;
    EXPECT_GT(early, 10) << name;
  }
}

// An engine that did not build the lists (a restart from a checkpoint, here a copy of the
// state) rebuilds the grid from the state and decides as the first engine does: the two runs
// stay bit for bit the same.
TEST(dem_BroadPhase, FarMoverCheckDecidesTheSameAfterARestart) {
  auto [scene, st] = far_mover_scene(FarCase::bed, 8);
  dem::Engine engine(scene, kEveryThread);
  auto drive = [&](dem::Engine& e, State& s, int steps) {
    for (int k = 0; k < steps; ++k) {
      s.tool_pose[0] = scene.tools[0].motion.evaluate(s.step * scene.dt);
      e.step(s);
    }
  };
  drive(engine, st, 150);
  State copy = st;
  const std::int64_t cleared_before = engine.guard_cleared();
  dem::Engine fresh(scene, kEveryThread);
  drive(engine, st, 400);
  drive(fresh, copy, 400);
  EXPECT_GT(fresh.guard_cleared(), 100);  // the check ran on the restored grid
  EXPECT_EQ(fresh.guard_cleared(), engine.guard_cleared() - cleared_before);
  EXPECT_EQ(st.rebuilds, copy.rebuilds);
  ASSERT_EQ(st.size(), copy.size());
  EXPECT_EQ(0, std::memcmp(st.x.data(), copy.x.data(), st.size() * sizeof(Vec3)));
  EXPECT_EQ(0, std::memcmp(st.v.data(), copy.v.data(), st.size() * sizeof(Vec3)));
}

TEST(dem_BroadPhase, StrictGuardThrowsNamingIntervalAndSkin) {
  auto [scene, st] = random_scene(1000, 0.1, 3, 1.0);
  scene.guard = dem::GuardMode::strict;
  dem::Engine engine(scene, kEveryThread);
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

// The pair list's distance test, 8 candidates at a time with AVX-512 or 4 at a time with AVX2
// (each where the processor has it), makes exactly the scalar test's decisions: same candidates
// in the same order, same count of touching ones, including distances that equal the cut-off or
// the contact distance in floating point (those are not hits: both compare with <) and rows of
// every length 0..19.
TEST(dem_BroadPhase, VectorRowTestMakesTheScalarDecisions) {
  if (!dem::detail::row_hits_vector_available())
    GTEST_SKIP() << "this processor has neither AVX-512F/VL nor AVX2: the pair list uses the "
                    "scalar test";
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1), ur(0.4, 0.6);
  const double skin = 0.2;
  const int n = 4000;
  std::vector<double> x(n), y(n), z(n), r(n);
  for (int k = 0; k < n; ++k) {
    x[k] = 1.5 * u(rng);
    y[k] = 1.5 * u(rng);
    z[k] = 1.5 * u(rng);
    r[k] = ur(rng);
  }
  const dem::detail::RowData d{x.data(), y.data(), z.data(), r.data()};
  int boundary_cases = 0, hits_total = 0, touching_total = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const std::int32_t a = trial * 7;
    const dem::Vec3 xa{x[a], y[a], z[a]};
    const double ra = r[a];
    // Some candidates exactly at the cut-off or at contact along x (d2 == cut^2 in doubles).
    bool exact[3];
    for (int e = 0; e < 3; ++e) {
      const std::int32_t b = a + 1 + e;
      const double rsum = ra + r[b];
      const double dist = e == 0 ? rsum + skin : (e == 1 ? rsum : 0.5 * rsum);
      x[b] = xa.x + dist;
      y[b] = xa.y;
      z[b] = xa.z;
      exact[e] = (x[b] - xa.x) == dist;
      boundary_cases += exact[e];
    }
    std::int32_t begin[5], end[5];
    int rows = 0;
    std::int32_t next = a - 3;  // the first row starts before a: only b > a count
    for (int q = 0; q < 5; ++q) {
      const std::int32_t len = (trial + 3 * q) % 20;
      if (next + len >= n) break;
      begin[q] = next;
      end[q] = next + len;
      next += len + (trial % 5);
      ++rows;
    }
    std::vector<std::int32_t> out_s(200, -1);
    std::int32_t touch_s = 0;
    const std::int32_t hs =
        dem::detail::row_hits_scalar(d, xa, ra, skin, a, begin, end, rows, out_s.data(), touch_s);
    // The processor's vector test (AVX-512, else AVX2) and the AVX2 one where it is another.
    for (const bool avx2 : {false, true}) {
      if (avx2 && !dem::detail::row_hits_avx2_available()) continue;
      std::vector<std::int32_t> out_v(200, -1);
      std::int32_t touch_v = 0;
      const std::int32_t hv =
          avx2 ? dem::detail::row_hits_avx2(d, xa, ra, skin, a, begin, end, rows, out_v.data(),
                                            touch_v)
               : dem::detail::row_hits_vector(d, xa, ra, skin, a, begin, end, rows,
                                              out_v.data(), touch_v);
      ASSERT_EQ(hs, hv) << "trial " << trial << (avx2 ? " avx2" : " vector");
      ASSERT_EQ(touch_s, touch_v) << "trial " << trial << (avx2 ? " avx2" : " vector");
      for (std::int32_t k = 0; k < hs; ++k) {
        ASSERT_EQ(out_s[k], out_v[k]) << "trial " << trial << " hit " << k;
        ASSERT_GT(out_s[k], a);
      }
    }
    // The scalar decisions against the definition, for the three placed candidates.
    std::set<std::int32_t> listed(out_s.begin(), out_s.begin() + hs);
    for (int e = 0; e < 3; ++e) {
      const std::int32_t b = a + 1 + e;
      bool in_rows = false;
      for (int q = 0; q < rows; ++q) in_rows |= b >= begin[q] && b < end[q];
      if (in_rows && exact[e]) {
        EXPECT_EQ(listed.count(b), e == 0 ? 0u : 1u) << "trial " << trial;
      }
    }
    hits_total += hs;
    touching_total += touch_s;
  }
  EXPECT_GT(boundary_cases, 600);  // most placed distances were exact in floating point
  EXPECT_GT(hits_total, 400);
  EXPECT_GT(touching_total, 400);
}

// A whole run gives the same bits with the vector pair-list test as with the scalar one: the
// claim that results do not depend on the processor (docs/dem.md, "Across processors").
// The vector row test (AVX-512, else AVX2) stores its hits as 8 or 4 lanes compressed in a
// register (not vpcompressd to memory, which is microcode on AMD's Zen 4 and 5): the same list,
// so the same run, on 1 and 2 threads and, for the vector test, through a checkpoint with a new
// engine.
TEST(dem_BroadPhase, RunIsBitIdenticalWithScalarAndVectorRowTest) {
  if (!dem::detail::row_hits_vector_available())
    GTEST_SKIP() << "this processor has neither AVX-512F/VL nor AVX2: only the scalar test can "
                    "run here";
  auto run = [](bool vector, int threads, bool through_checkpoint) {
    dem::EngineOptions options = kEveryThread;
    options.vector_row_test = vector;
    auto [scene, st] = random_scene(5, 0.4, 23, 0.3);
    scene.threads = threads;
    run_with_tool(scene, options, st, 800, through_checkpoint ? 400 : -1, "dem_row_test_",
                  [](const dem::Engine&) {});
    return st;
  };
  auto same_bits = [](const std::vector<dem::Vec3>& p, const std::vector<dem::Vec3>& q) {
    return p.size() == q.size() && std::memcmp(p.data(), q.data(), p.size() * sizeof(dem::Vec3)) == 0;
  };
  auto [scene0, st0] = random_scene(5, 0.4, 23, 0.3);
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    const State a = run(true, threads, true), b = run(false, threads, false);
    ASSERT_EQ(a.size(), b.size());
    ASSERT_GT(a.rebuilds, 100);
    EXPECT_GT(a.pair_j.size(), 50u);  // the lists were not empty
    EXPECT_TRUE(same_bits(a.x, b.x));
    EXPECT_TRUE(same_bits(a.v, b.v));
    EXPECT_TRUE(same_bits(a.pair_spring, b.pair_spring));
    EXPECT_EQ(a.pair_j, b.pair_j);
    // The run moved: a bit-identity of particles at rest would say little.
    double moved = 0;
    for (std::size_t i = 0; i < a.size(); ++i) moved += dem::norm(a.x[i] - st0.x[i]) > 0;
    EXPECT_GT(moved, 0.5 * a.size());
  }
}

// The history carried over by copying the rows that kept their particle and partners gives the
// same bits as looking every held spring up in its new row (EngineOptions::history_same_rows):
// a slow bed rebuilt every 5 steps, where most rows keep their partners and some particles
// change cells, on 1 and 2 threads, through a checkpoint with a new engine, translating and
// rotating (whose rolling springs go with the tangential ones).
TEST(dem_BroadPhase, RunIsBitIdenticalWithHistoryCopiedOrLookedUp) {
  auto run = [](bool same_rows, int threads, bool rotating, bool through_checkpoint,
                std::int64_t* copied, std::int64_t* looked_up) {
    dem::EngineOptions options = kEveryThread;
    options.history_same_rows = same_rows;
    auto [scene, st] = random_scene(5, 0.4, 29, 0.05);
    scene.threads = threads;
    scene.gravity = {0, 0, -9.81};
    if (rotating) {
      scene.rotation.model = dem::ParticleModel::rotating;
      scene.rotation.rolling.kind = dem::RollingResistance::Kind::epsd;
      scene.rotation.rolling.friction = 0.1;
    }
    *copied = *looked_up = 0;
    run_with_tool(scene, options, st, 1000, through_checkpoint ? 500 : -1, "dem_history_rows_",
                  [&](const dem::Engine& engine) {
                    *copied += engine.broad_phase().history_rows_copied();
                    *looked_up += engine.broad_phase().history_rows_looked_up();
                  });
    return st;
  };
  auto same_bits = [](const std::vector<dem::Vec3>& p, const std::vector<dem::Vec3>& q) {
    return p.size() == q.size() && std::memcmp(p.data(), q.data(), p.size() * sizeof(dem::Vec3)) == 0;
  };
  auto [scene0, st0] = random_scene(5, 0.4, 29, 0.05);
  for (const bool rotating : {false, true})
    for (int threads : {1, 2}) {
      SCOPED_TRACE(std::string(rotating ? "rotating" : "translating") + ", threads " +
                   std::to_string(threads));
      std::int64_t copied_a, looked_a, copied_b, looked_b;
      const State a = run(true, threads, rotating, true, &copied_a, &looked_a);
      const State b = run(false, threads, rotating, false, &copied_b, &looked_b);
      ASSERT_EQ(a.size(), b.size());
      ASSERT_GE(a.rebuilds, 190);
      // Both ways of carrying ran: rows copied and rows looked up (partners changed).
      EXPECT_GT(copied_a, 10 * looked_a / 100) << looked_a;
      EXPECT_GT(looked_a, 100) << copied_a;
      EXPECT_EQ(copied_b, 0);
      std::size_t held = 0;
      for (const dem::Vec3& sp : a.pair_spring) held += dem::nonzero(sp);
      EXPECT_GT(held, 20u);  // there was history to carry
      EXPECT_TRUE(same_bits(a.x, b.x));
      EXPECT_TRUE(same_bits(a.v, b.v));
      EXPECT_TRUE(same_bits(a.pair_spring, b.pair_spring));
      EXPECT_EQ(a.pair_j, b.pair_j);
      if (rotating) {
        EXPECT_TRUE(same_bits(a.w, b.w));
        EXPECT_TRUE(same_bits(a.pair_roll, b.pair_roll));
      }
      double moved = 0;
      for (std::size_t i = 0; i < a.size(); ++i) moved += dem::norm(a.x[i] - st0.x[i]) > 0;
      EXPECT_GT(moved, 0.5 * a.size());
    }
}
