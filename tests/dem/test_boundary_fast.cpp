// The boundary contacts' fast path (docs/performance.md "The boundary contacts"): the particles'
// lines fetched ahead, a resting contact's spring kept without the search, the springs' scratch
// not zeroed for every particle. It gives the bits of the reference path
// (EngineOptions::boundary_fast off, the code before it): every step's tool wrench, wall
// forces and contact statistics and the final state (springs, slot keys and counts included), on
// 1 and 2 threads, with the translating and the rotating model, sleeping, more than 32 walls,
// through a checkpoint, and the same error for a particle with too many boundary contacts.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <set>
#include <string>

#include "dem/boundary_contacts.hpp"
#include "dem/checkpoint.hpp"
#include "dem/mesh_contact.hpp"
#include "dem_test_util.hpp"

namespace {

using demtest::Vec3;

constexpr int kGrains = 3000;
constexpr int kSteps = 400;
constexpr double kDt = 2e-5;  // the dt of demtest::thrown_lattice_scene

struct Variant {
  const char* name;
  bool rotating = false;
  bool sleep = false;
  bool many_walls = false;  // 31 far walls more: 36 in all, every wall tested for every grain
};

dem::Wall plane(const char* name, Vec3 point, Vec3 normal) {
  dem::Wall w;
  w.name = name;
  w.point = point;
  w.normal = (1 / dem::norm(normal)) * normal;
  return w;
}

// The thrown lattice (demtest::thrown_lattice: 3000 grains, creeping, one in 25 thrown) on its
// floor, in a box of three side walls (the back one with a stiffer law of its own), with a
// wedge (two quads meeting at a vertical edge, and a roof) pushed into its open side and turned
// about z: grains rest on the floor and in the corners, slide along the wedge's faces onto its
// edge, vertices and the next face, and are thrown against all of them.
dem::Scene box_scene(int threads, const Variant& v) {
  dem::Scene scene = demtest::thrown_lattice_scene(threads);
  scene.walls.push_back(plane("left", {-1.5e-3, 0, 0}, {1, 0, 0}));
  scene.walls.push_back(plane("front", {0, -1.5e-3, 0}, {0, 1, 0}));
  scene.walls.push_back(plane("back", {0, 26.8e-3, 0}, {0, -1, 0}));
  scene.boundary_laws.push_back(demtest::law_n_per_m(900, 0.4, true, 0.3));
  scene.walls.back().law = 0;
  // A ceiling far above: a fifth wall no grain reaches.
  scene.walls.push_back(plane("ceiling", {0, 0, 0.5}, {0, 0, -1}));
  if (v.many_walls)
    for (int k = 0; k < 31; ++k) {
      const double a = 2 * M_PI * k / 31;
      scene.walls.push_back(
          plane("far", {1.0 * std::cos(a), 1.0 * std::sin(a), 0}, {-std::cos(a), -std::sin(a), 0.1}));
    }
  // The wedge, in its own frame: the edge along z at the origin, the faces opening to +x.
  std::vector<Vec3> corners;
  const Vec3 e0{0, 0, -1e-3}, e1{0, 0, 0.03};
  const Vec3 l0{9e-3, -8e-3, -1e-3}, l1{9e-3, -8e-3, 0.03};
  const Vec3 r0{9e-3, 8e-3, -1e-3}, r1{9e-3, 8e-3, 0.03};
  demtest::quad(corners, e0, l0, l1, e1);
  demtest::quad(corners, r0, e0, e1, r1);
  corners.insert(corners.end(), {e1, l1, r1});  // the roof
  dem::Tool wedge = demtest::static_tool("wedge", corners);
  const double turn = 0.15;  // rad about z over the run
  wedge.motion.keyframes = {
      {0, {0.030, 0.0126, 0}, {1, 0, 0, 0}},
      {kSteps * kDt, {0.018, 0.0126, -0.002}, {std::cos(turn / 2), 0, 0, std::sin(turn / 2)}}};
  dem::validate_keyframes(wedge.motion.keyframes, "test");
  scene.tools.push_back(wedge);
  if (v.rotating) {
    scene.rotation.model = dem::ParticleModel::rotating;
    scene.rotation.rolling.kind = dem::RollingResistance::Kind::epsd;
    scene.rotation.rolling.friction = 0.1;
    scene.rotation.rolling.damping = 0.3;
  }
  if (v.sleep) {
    scene.sleep.enabled = true;
    scene.sleep.speed = 2e-2;
    scene.sleep.steps = 20;
    scene.sleep.neighbourhood = dem::SleepNeighbourhood::box;
    scene.sleep.tool_distance = 1e-3;
  }
  return scene;
}

// The thrown lattice moving as a whole towards the floor, the left and the back wall at 0.3,
// 0.25 and 0.25 m/s: the grains of its sides hit them, bounce and come to rest in the run.
dem::State lattice_state() {
  dem::State st = demtest::thrown_lattice(kGrains);
  for (std::size_t i = 0; i < st.size(); ++i) {
    st.v[i] = st.v[i] + Vec3{-0.25, 0.25, -0.3};
    st.u[i] = st.v[i];
  }
  return st;
}

// reference: the boundary contacts as before the fast path (EngineOptions::boundary_fast off).
dem::EngineOptions options(bool reference = false) {
  dem::EngineOptions o;
  o.min_particles_per_thread = 100;  // every thread asked for
  o.boundary_fast = !reference;
  return o;
}

bool same_bits(const void* a, const void* b, std::size_t n) { return std::memcmp(a, b, n) == 0; }

// What a run gives, step by step.
struct Outputs {
  dem::State state;
  std::vector<dem::Wrench> wedge;
  std::vector<std::vector<Vec3>> walls;
  std::vector<dem::ContactStats> stats;
  std::set<int> kinds;  // the kinds of mesh feature the grains touched (face, edge, vertex)
  std::int64_t sleeping_steps = 0;  // steps with sleepers
};

void step_and_record(const dem::Scene& scene, dem::Engine& e, Outputs& r) {
  r.state.tool_pose[0] = scene.tools[0].motion.evaluate(r.state.step * scene.dt);
  e.step(r.state);
  r.wedge.push_back(e.tool_wrenches()[0]);
  r.walls.push_back(e.wall_forces());
  r.stats.push_back(e.contact_stats());
  r.sleeping_steps += e.sleeping() > 0;
  if (r.state.step % 20 == 0)
    for (const auto& c : e.mesh_contacts(r.state))
      r.kinds.insert(static_cast<int>(dem::key_kind(c.key)));
}

Outputs run(const dem::Scene& scene, bool reference, int steps = kSteps) {
  Outputs r;
  r.state = lattice_state();
  dem::Engine e(scene, options(reference));
  for (int k = 0; k < steps; ++k) step_and_record(scene, e, r);
  return r;
}

// The first step whose recorded outputs differ, or -1.
int first_difference(const Outputs& a, const Outputs& b) {
  if (a.wedge.size() != b.wedge.size()) return 0;
  for (std::size_t k = 0; k < a.wedge.size(); ++k) {
    const dem::ContactStats &sa = a.stats[k], &sb = b.stats[k];
    if (!same_bits(&a.wedge[k], &b.wedge[k], sizeof(dem::Wrench)) ||
        a.walls[k].size() != b.walls[k].size() ||
        !same_bits(a.walls[k].data(), b.walls[k].data(), a.walls[k].size() * sizeof(Vec3)) ||
        sa.particle_contacts != sb.particle_contacts ||
        sa.boundary_contacts != sb.boundary_contacts ||
        !same_bits(&sa.max_overlap, &sb.max_overlap, sizeof(double)) ||
        !same_bits(&sa.max_overlap_ratio, &sb.max_overlap_ratio, sizeof(double)))
      return static_cast<int>(k);
  }
  return -1;
}

std::string describe(const Variant& v, int threads) {
  return std::string(v.name) + ", " + std::to_string(threads) + " thread" + (threads > 1 ? "s" : "");
}

// The run means something: the grains touch the floor, the side walls and the wedge (faces and
// edges or vertices), contacts begin and end, and the springs are loaded.
void expect_busy_boundary(const Outputs& r, const std::string& what) {
  std::int64_t hi = 0, drops = 0;
  for (std::size_t k = 0; k < r.stats.size(); ++k) {
    hi = std::max(hi, r.stats[k].boundary_contacts);
    drops += k > 0 && r.stats[k].boundary_contacts < r.stats[k - 1].boundary_contacts;
  }
  EXPECT_GT(hi, 150) << what;
  EXPECT_GT(drops, 10) << what;  // contacts end (and begin: none at the start)
  EXPECT_GT(std::abs(r.wedge.back().force.x), 0.0) << what;
  EXPECT_GT(std::abs(r.walls.back()[0].z), 0.0) << what;  // floor
  EXPECT_GT(std::abs(r.walls.back()[1].x), 0.0) << what;  // left
  EXPECT_GT(std::abs(r.walls.back()[3].y), 0.0) << what;  // back, its own law
  EXPECT_EQ(r.walls.back()[2].y, 0.0) << what;            // front: the lattice moves away
  EXPECT_EQ(r.walls.back()[4].z, 0.0) << what;            // the ceiling, never reached
  EXPECT_GE(r.kinds.size(), 2u) << what;  // a face and an edge or vertex
  double loaded = 0;
  for (const Vec3& sp : r.state.slot_spring) loaded = std::max(loaded, dem::norm(sp));
  EXPECT_GT(loaded, 0.0) << what;
}

TEST(dem_BoundaryFast, SameBitsAsTheReferencePath) {
  for (const Variant& v :
       {Variant{"translating"}, Variant{"rotating", true}, Variant{"sleeping", false, true},
        Variant{"rotating, 36 walls", true, false, true}}) {
    for (const int threads : {1, 2}) {
      const std::string what = describe(v, threads);
      const dem::Scene scene = box_scene(threads, v);
      const Outputs ref = run(scene, true);
      const Outputs fast = run(scene, false);
      EXPECT_EQ(first_difference(ref, fast), -1) << what;
      EXPECT_EQ(dem::differing_arrays(ref.state, fast.state), "") << what;
      expect_busy_boundary(fast, what);
      if (v.sleep) {
        EXPECT_GT(fast.sleeping_steps, kSteps / 4) << what;
      }
      std::printf("%s: %lld boundary contacts at the end, %zu feature kinds on the wedge, %lld "
                  "steps with sleepers\n",
                  what.c_str(), static_cast<long long>(fast.stats.back().boundary_contacts),
                  fast.kinds.size(), static_cast<long long>(fast.sleeping_steps));
    }
  }
}

// The fast path on two threads, saved half way and continued by a fresh engine from the file,
// against the reference path on one thread: the same bits step by step and at the end.
TEST(dem_BoundaryFast, TwoThreadsThroughACheckpointGiveTheReferenceBitsOfOne) {
  for (const Variant& v : {Variant{"translating"}, Variant{"rotating", true}}) {
    const std::string what = v.name;
    const Outputs ref = run(box_scene(1, v), true);
    const dem::Scene two_scene = box_scene(2, v);
    Outputs two;
    two.state = lattice_state();
    {
      dem::Engine e(two_scene, options());
      for (int k = 0; k < kSteps / 2 + 3; ++k) step_and_record(two_scene, e, two);
      ASSERT_EQ(e.threads(), 2) << what;
    }
    const std::string file = (std::filesystem::temp_directory_path() /
                              ("dem_boundary_fast_" + std::to_string(v.rotating) + ".h5"))
                                 .string();
    dem::save_checkpoint(two.state, file);
    two.state = dem::load_checkpoint(file);
    std::filesystem::remove(file);
    dem::Engine e(two_scene, options());  // a fresh engine: nothing kept in its workspace
    while (two.wedge.size() < static_cast<std::size_t>(kSteps)) step_and_record(two_scene, e, two);
    EXPECT_EQ(first_difference(ref, two), -1) << what;
    EXPECT_EQ(dem::differing_arrays(ref.state, two.state), "") << what;
  }
}

// A grain inside a cage of 9 walls (more than kBoundarySlots) stops the step with the same
// message on both paths, on 1 and 2 threads, before anything moves.
TEST(dem_BoundaryFast, TooManyBoundaryContactsGiveTheSameError) {
  for (const int threads : {1, 2}) {
    std::string messages[2];
    for (const bool reference : {true, false}) {
      auto [scene, st] = demtest::caged_pair_scene(threads);
      dem::EngineOptions o = options(reference);
      o.min_particles_per_thread = 1;
      dem::Engine e(scene, o);
      e.prepare(st);
      const std::vector<Vec3> x = st.x;
      try {
        e.step(st);
      } catch (const dem::SimulationError& err) {
        messages[reference] = err.what();
      }
      EXPECT_EQ(std::memcmp(x.data(), st.x.data(), x.size() * sizeof(Vec3)), 0);
    }
    const std::string what = std::to_string(threads) + " threads";
    EXPECT_NE(messages[0].find("touches more than 8 walls"), std::string::npos)
        << what << ": " << messages[0];
    EXPECT_EQ(messages[0], messages[1]) << what;
  }
}

// A grain of radius 10 mm resting 9 mm above a fine flat grid of n x n quads 6 mm wide: every
// triangle is within its reach, so it has 2 n^2 triangle hits. 10 x 10 (200 hits, fewer than
// kMaxHits = 256): the same bits on both paths for 50 steps, the grain held up by the grid; 12 x
// 12 (288): the same error on both paths, before anything moves.
TEST(dem_BoundaryFast, ManyTriangleHitsGiveTheSameBitsOrTheSameError) {
  for (const int n : {10, 12}) {
    std::string messages[2];
    dem::State states[2];
    dem::Wrench wrench[2];
    for (const bool reference : {true, false}) {
      dem::Scene scene = demtest::one_species_scene(0.01, 0.01);
      scene.particle_particle = scene.particle_wall = demtest::law_n_per_m(1e3, 0.5, true, 0.4);
      scene.dt = 1e-4;
      scene.gravity = {0, 0, -9.81};
      std::vector<Vec3> corners;
      const double h = 6e-3 / n;
      for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) {
          const double x = -3e-3 + a * h, y = -3e-3 + b * h;
          demtest::quad(corners, {x, y, 0}, {x + h, y, 0}, {x + h, y + h, 0}, {x, y + h, 0});
        }
      scene.tools.push_back(demtest::static_tool("grid", corners));
      dem::State st;
      demtest::add(st, {0.2e-3, -0.1e-3, 9e-3}, {0.01, 0, 0}, 0.01);
      st.tool_pose.resize(1);
      dem::Engine e(scene, options(reference));
      e.prepare(st);
      const std::vector<Vec3> x = st.x;
      try {
        for (int k = 0; k < 50; ++k) e.step(st);
        wrench[reference] = e.tool_wrenches()[0];
      } catch (const dem::SimulationError& err) {
        messages[reference] = err.what();
        EXPECT_EQ(std::memcmp(x.data(), st.x.data(), x.size() * sizeof(Vec3)), 0);
      }
      states[reference] = st;
    }
    const std::string what = std::to_string(n) + " x " + std::to_string(n) + " quads";
    EXPECT_EQ(messages[0], messages[1]) << what;
    EXPECT_EQ(dem::differing_arrays(states[0], states[1]), "") << what;
    EXPECT_TRUE(same_bits(&wrench[0], &wrench[1], sizeof(dem::Wrench))) << what;
    if (n == 10) {
      EXPECT_EQ(messages[0], "") << what;
      EXPECT_LT(wrench[0].force.z, 0.0) << what;  // the grain pushes the grid down
      EXPECT_EQ(states[0].slot_count[0], 1) << what;  // one face after feature selection
    } else {
      EXPECT_NE(messages[0].find("touches more than 8 walls and mesh features"), std::string::npos)
          << what << ": " << messages[0];
    }
  }
}

}  // namespace
