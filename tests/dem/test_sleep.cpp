// Sleeping particles (scene.sleep) and the region of interest (scene.region): a bed at rest
// falls asleep, a sleeping column holds the closed-form static overlaps, sleepers wake when hit
// or when a tool comes near, sleep that never triggers changes nothing (bit for bit), runs with
// the same thread count stay bit-identical with sleepers, removal keeps the lists and the
// tangential history of the others, bad values are refused naming the key.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <random>

#include "cosim/yaml_config.hpp"
#include "dem/checkpoint.hpp"
#include "dem/config.hpp"
#include "dem_test_util.hpp"

namespace {

using namespace demtest;
using dem::State;

constexpr double kR = 0.005;
constexpr double kK = 2e4;  // N/m
constexpr double kG = 9.81;

std::int64_t asleep(const dem::Scene& sc, const State& st) {
  std::int64_t n = 0;
  for (const std::int32_t r : st.rest_steps) n += r >= sc.sleep.steps;
  return n;
}
bool is_asleep(const dem::Scene& sc, const State& st, std::int64_t id) {
  return st.rest_steps[index_of(st, id)] >= sc.sleep.steps;
}

// A vertical column of equal spheres on a plane floor, frictionless, released 1 mm apart.
struct Column {
  dem::Scene scene;
  State st;
};

Column make_column(int count, double speed) {
  Column c;
  c.scene = one_species_scene(kR, kR);
  c.scene.gravity = {0, 0, -kG};
  c.scene.particle_particle = c.scene.particle_wall = law_n_per_m(kK, 0.3, true);
  c.scene.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}});
  c.scene.dt = M_PI / std::sqrt(kK / sphere_mass(kR)) / 40;
  c.scene.sleep.enabled = true;
  c.scene.sleep.speed = speed;
  c.scene.sleep.steps = 200;
  c.scene.sleep.tool_distance = 0.02;
  for (int k = 0; k < count; ++k) add(c.st, {0, 0, kR + 0.001 + k * (2 * kR + 0.001)}, {}, kR);
  return c;
}

// Static column: the contact under sphere k (k = 0 at the floor) carries the weight of the
// spheres k..n-1, so its overlap is (n - k) m g / k_N; the centre heights follow.
std::vector<double> closed_form_heights(int n) {
  const double w = sphere_mass(kR) * kG;
  std::vector<double> z(n);
  double h = 0;
  for (int k = 0; k < n; ++k) {
    const double overlap = (n - k) * w / kK;
    h += (k == 0 ? kR : 2 * kR) - overlap;
    z[k] = h;
  }
  return z;
}

double worst_height_error(const State& st, int n) {
  const auto z = closed_form_heights(n);
  double worst = 0;
  for (int k = 0; k < n; ++k) worst = std::max(worst, std::abs(st.x[index_of(st, k)].z - z[k]));
  return worst;
}

TEST(dem_Sleep, SettledColumnSleepsInPlaceAndWakesWhenHit) {
  Column c = make_column(5, 1e-5);
  dem::Engine e(c.scene);
  while (c.st.step * c.scene.dt < 1.0) e.step(c.st);
  const double overlap0 = 5 * sphere_mass(kR) * kG / kK;  // the floor contact, 3.2 um
  EXPECT_EQ(e.sleeping(), 5);
  EXPECT_EQ(asleep(c.scene, c.st), 5);
  std::printf("asleep column: worst height error %.2e m (floor overlap %.2e m)\n",
              worst_height_error(c.st, 5), overlap0);
  EXPECT_LT(worst_height_error(c.st, 5), 0.01 * overlap0);
  // Asleep: nothing moves, bit for bit, and nothing wakes.
  const std::vector<Vec3> x = c.st.x;
  for (int k = 0; k < 2000; ++k) e.step(c.st);
  EXPECT_EQ(0, std::memcmp(x.data(), c.st.x.data(), x.size() * sizeof(Vec3)));
  EXPECT_EQ(e.sleeping(), 5);

  // A sixth sphere dropped from 2 cm wakes the column; it settles and sleeps again at the
  // closed form of six.
  add(c.st, {0, 0, c.st.x[index_of(c.st, 4)].z + 2 * kR + 0.02}, {}, kR);
  bool top_woke = false;
  std::int64_t fewest = 6;
  while (c.st.step * c.scene.dt < 3.0) {
    e.step(c.st);
    top_woke = top_woke || !is_asleep(c.scene, c.st, 4);
    fewest = std::min(fewest, e.sleeping());
  }
  EXPECT_TRUE(top_woke);
  EXPECT_EQ(fewest, 0) << "the impact should wake the whole column";
  EXPECT_EQ(e.sleeping(), 6);
  // The churn the end-of-run notes report: five fell asleep, all five woke, six fell asleep
  // again (each transition counted once; more if a sphere dozed off and woke during settling).
  EXPECT_EQ(e.fell_asleep_total() - e.woke_total(), 6);
  EXPECT_GE(e.woke_total(), 5);
  EXPECT_GE(e.fell_asleep_total(), 11);
  const double overlap6 = 6 * sphere_mass(kR) * kG / kK;
  std::printf("after the hit: worst height error %.2e m (floor overlap %.2e m)\n",
              worst_height_error(c.st, 6), overlap6);
  EXPECT_LT(worst_height_error(c.st, 6), 0.01 * overlap6);
}

// Sphere B slides at 5 mm/s into sphere A, asleep (elastic, no gravity, no friction); both are
// slower than `speed` (10 mm/s). With the default wake speed (= speed) A stays asleep, a fixed
// body: B rebounds at -v (elastic against a fixed body), A does not move a bit. With
// wake_speed 2 mm/s A wakes on contact: equal masses, elastic and head-on, the velocities are
// exchanged (A leaves at v, B stops).
TEST(dem_Sleep, WakeSpeedBelowSpeedLetsASlowPushWakeASleeper) {
  const double v = 0.005;
  struct Out {
    Vec3 va, vb, xa;
    bool a_woke;
    double dt;
  };
  auto collide = [&](double wake_speed) {
    Column c = make_column(1, 0.01);
    c.scene.gravity = {0, 0, 0};
    c.scene.walls.clear();
    c.scene.particle_particle = law_n_per_m(kK, 1.0, true);
    c.scene.sleep.steps = 1000;
    c.scene.sleep.wake_speed = wake_speed;
    dem::Engine e(c.scene);
    for (int k = 0; k < 1100; ++k) e.step(c.st);
    EXPECT_EQ(e.sleeping(), 1);
    const Vec3 xa = c.st.x[0];
    // B starts 10 steps of travel short of contact, on A's axis; the contact lasts about
    // 40 steps against a fixed body, 28 between two free ones. 300 steps: long over.
    add(c.st, {xa.x - 2 * kR - 10 * v * c.scene.dt, xa.y, xa.z}, {v, 0, 0}, kR);
    bool woke = false;
    for (int k = 0; k < 300; ++k) {
      e.step(c.st);
      woke = woke || !is_asleep(c.scene, c.st, 0);
    }
    return Out{c.st.v[index_of(c.st, 0)], c.st.v[index_of(c.st, 1)], c.st.x[index_of(c.st, 0)] - xa,
               woke, c.scene.dt};
  };
  const Out fixed = collide(0);  // 0: wake at speed
  EXPECT_FALSE(fixed.a_woke);
  EXPECT_EQ(fixed.xa.x, 0.0);
  EXPECT_EQ(fixed.va.x, 0.0);
  EXPECT_NEAR(fixed.vb.x, -v, 0.01 * v) << "elastic rebound from a fixed sleeper";
  const Out pushed = collide(0.002);
  EXPECT_TRUE(pushed.a_woke);
  EXPECT_NEAR(pushed.va.x, v, 0.02 * v) << "A takes B's velocity";
  EXPECT_NEAR(pushed.vb.x, 0.0, 0.02 * v) << "B stops";
  // A leaves about 40 steps after B was added and moves at v for the remaining 260
  EXPECT_NEAR(pushed.xa.x, 260 * v * pushed.dt, 20 * v * pushed.dt) << "A moved on at v";
  std::printf("fixed sleeper: B %.6f m/s; woken: A %.6f, B %.6f m/s (v = %.3f)\n", fixed.vb.x,
              pushed.va.x, pushed.vb.x, v);
}

// A free particle slower than `speed` near its apex must not fall asleep in the air (the
// config refuses steps shorter than the apex time; here they are just longer).
TEST(dem_Sleep, BallThrownUpDoesNotSleepAtTheApex) {
  Column c = make_column(1, 0.01);
  c.scene.sleep.steps = static_cast<int>(2 * 0.01 / (kG * c.scene.dt)) + 5;
  c.st.x[0].z = 0.1;
  c.st.v[0] = c.st.u[0] = {0, 0, 0.5};
  dem::Engine e(c.scene);
  const double t_apex = 0.5 / kG;
  while (c.st.step * c.scene.dt < 2 * t_apex) {
    e.step(c.st);
    ASSERT_EQ(e.sleeping(), 0) << "asleep in flight at t = " << c.st.step * c.scene.dt;
  }
  // Free flight is untouched by the sleep bookkeeping: z(t) of semi-implicit Euler.
  const double t = c.st.step * c.scene.dt;
  EXPECT_NEAR(c.st.x[0].z, 0.1 + 0.5 * t - 0.5 * kG * t * t, 1e-3);
}

TEST(dem_Sleep, ToolNeighbourhoodWakesOnlyTheParticlesNearIt) {
  Column c = make_column(5, 1e-5);
  // A small triangle around its reference point (bounding radius 1 cm), parked far away.
  c.scene.tools.push_back(static_tool("probe", {{0.01, 0, 0}, {-0.005, 0.0087, 0}, {-0.005, -0.0087, 0}}));
  c.st.tool_pose.resize(1);
  c.st.tool_pose[0].position = {1, 0, 1};
  dem::Engine e(c.scene);
  while (c.st.step * c.scene.dt < 1.0) e.step(c.st);
  ASSERT_EQ(e.sleeping(), 5);
  const double rb = c.scene.tools[0].mesh.bounding_radius;
  ASSERT_NEAR(rb, 0.01, 1e-4);
  // Beside the top sphere: gap to spheres 4 and 3 below tool_distance (2 cm), to 2 above it.
  const Vec3 top = c.st.x[index_of(c.st, 4)];
  c.st.tool_pose[0].position = {top.x + 0.03, 0, top.z};
  auto gap = [&](int id) {
    return norm(c.st.x[index_of(c.st, id)] - c.st.tool_pose[0].position) - rb - kR;
  };
  ASSERT_LT(gap(4), 0.02);
  ASSERT_LT(gap(3), 0.02);
  ASSERT_GT(gap(2), 0.02);
  const std::vector<Vec3> x = c.st.x;
  for (int k = 0; k < 1000; ++k) e.step(c.st);
  EXPECT_FALSE(is_asleep(c.scene, c.st, 4));
  EXPECT_FALSE(is_asleep(c.scene, c.st, 3));
  for (int id : {0, 1, 2}) EXPECT_TRUE(is_asleep(c.scene, c.st, id)) << id;
  // The two awake spheres rest on sleeper 2: its contact force holds them where they were.
  for (int id : {3, 4})
    EXPECT_LT(norm(c.st.x[index_of(c.st, id)] - x[index_of(c.st, id)]),
              0.01 * sphere_mass(kR) * kG / kK)
        << id;
  // The tool leaves: they fall asleep again.
  c.st.tool_pose[0].position = {1, 0, 1};
  for (int k = 0; k < 400; ++k) e.step(c.st);
  EXPECT_EQ(e.sleeping(), 5);
}

// neighbourhood: box measures the gap to the mesh's box in the tool frame. A thin plate, 20 mm
// long from its reference point along its own x, is turned 90 degrees about y (its x points
// down) and parked 15 mm beside the settled column (centres 10 mm apart) at the height of
// sphere 3: it spans spheres 1-3. With tool_distance 11.5 mm (reach 16.5 mm with the radius)
// spheres 1-3 (15 mm from the plate) wake, 0 and 4 (18.0 mm from its ends) sleep on. The
// bounding sphere (radius 20.6 mm about the reference point) wakes all five. Ignoring the rotation would wake only
// sphere 3, rotating the wrong way spheres 3 and 4.
TEST(dem_Sleep, BoxNeighbourhoodFollowsTheToolsOrientation) {
  for (const auto shape : {dem::SleepNeighbourhood::box, dem::SleepNeighbourhood::sphere}) {
    const bool box = shape == dem::SleepNeighbourhood::box;
    Column c = make_column(5, 1e-5);
    c.scene.sleep.tool_distance = 0.0115;
    c.scene.sleep.neighbourhood = shape;
    std::vector<Vec3> plate;
    quad(plate, {0, -0.005, 0}, {0.020, -0.005, 0}, {0.020, 0.005, 0}, {0, 0.005, 0});
    c.scene.tools.push_back(static_tool("plate", plate));
    c.st.tool_pose.resize(1);
    c.st.tool_pose[0].position = {1, 0, 1};
    dem::Engine e(c.scene);
    while (c.st.step * c.scene.dt < 1.0) e.step(c.st);
    ASSERT_EQ(e.sleeping(), 5);
    const Vec3 x3 = c.st.x[index_of(c.st, 3)];
    c.st.tool_pose[0].position = {x3.x + 0.015, x3.y, x3.z};
    c.st.tool_pose[0].orientation = {std::cos(M_PI / 4), 0, std::sin(M_PI / 4), 0};
    // One step: the tool's neighbourhood wakes particles when they are integrated; nothing
    // moved yet, so no contact wakes another.
    e.step(c.st);
    for (int id : {1, 2, 3}) EXPECT_FALSE(is_asleep(c.scene, c.st, id)) << id << (box ? " box" : " sphere");
    for (int id : {0, 4}) EXPECT_EQ(is_asleep(c.scene, c.st, id), box) << id << (box ? " box" : " sphere");
  }
}

// The 150-sphere pile of dem_pile_test, frictional, on a plane.
struct Pile {
  dem::Scene scene;
  State st;
};
// The piles use every thread they ask for, however few their particles.
const dem::EngineOptions kPileOptions = [] {
  dem::EngineOptions o;
  o.min_particles_per_thread = 1;
  return o;
}();

Pile make_pile(int threads, bool sleep) {
  Pile p;
  p.scene = one_species_scene(0.8 * kR, kR);
  p.scene.gravity = {0, 0, -kG};
  p.scene.threads = threads;
  p.scene.particle_particle = p.scene.particle_wall = law_n_per_m(kK, 0.3, true, 0.5, 1.0, 0.5);
  p.scene.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}});
  p.scene.dt = M_PI / std::sqrt(kK / sphere_mass(0.8 * kR)) / 25;
  p.scene.sleep.enabled = sleep;
  p.scene.sleep.speed = 0.005;
  p.scene.sleep.steps = 200;
  add_jittered_block(p.st, kR, 7);
  return p;
}

TEST(dem_Sleep, BedAtRestFallsAsleep) {
  Pile p = make_pile(1, true);
  dem::Engine e(p.scene, kPileOptions);
  std::int64_t at_half = -1;
  while (p.st.step * p.scene.dt < 2.0) {
    e.step(p.st);
    if (at_half < 0 && p.st.step * p.scene.dt >= 0.05) at_half = e.sleeping();
  }
  std::printf("asleep: %lld of 150 at 0.05 s (falling), %lld at 2 s\n",
              static_cast<long long>(at_half), static_cast<long long>(e.sleeping()));
  EXPECT_EQ(at_half, 0);
  EXPECT_EQ(e.sleeping(), 150);
  EXPECT_EQ(asleep(p.scene, p.st), 150);
  EXPECT_EQ(dem::kinetic_energy(p.st), 0.0);
}

// Sleep enabled with a speed nobody gets below runs the same loops with the sleeper rules;
// with no sleeper the result must be the all-active one, bit for bit.
TEST(dem_Sleep, SleepThatNeverTriggersIsBitIdenticalToDisabled) {
  for (int threads : {1, 2}) {
    Pile a = make_pile(threads, false), b = make_pile(threads, true);
    b.scene.sleep.speed = 1e-300;
    dem::Engine ea(a.scene, kPileOptions), eb(b.scene, kPileOptions);
    for (int k = 0; k < 3000; ++k) {
      ea.step(a.st);
      eb.step(b.st);
    }
    EXPECT_EQ(eb.sleeping(), 0);
    ASSERT_EQ(a.st.size(), b.st.size());
    EXPECT_EQ(0, std::memcmp(a.st.x.data(), b.st.x.data(), a.st.size() * sizeof(Vec3)))
        << threads << " threads";
    EXPECT_EQ(0, std::memcmp(a.st.v.data(), b.st.v.data(), a.st.size() * sizeof(Vec3)));
    EXPECT_EQ(0, std::memcmp(a.st.pair_spring.data(), b.st.pair_spring.data(),
                             a.st.pair_spring.size() * sizeof(Vec3)));
    EXPECT_EQ(0, std::memcmp(&ea.wall_forces()[0], &eb.wall_forces()[0], sizeof(Vec3)));
  }
}

// Same thread count, sleep on, a ball dropped into the half-asleep pile: bit-identical runs
// (1 and 2 threads), and a checkpoint restored mid-way continues bit for bit.
TEST(dem_Sleep, SameThreadCountIsBitIdenticalWithSleepers) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "dem_sleep_checkpoint.h5").string();
  for (int threads : {1, 2}) {
    Pile a = make_pile(threads, true), b = make_pile(threads, true);
    dem::Engine ea(a.scene, kPileOptions), eb(b.scene, kPileOptions);
    std::int64_t max_asleep = 0;
    auto run = [&](int steps) {
      for (int k = 0; k < steps; ++k) {
        ea.step(a.st);
        eb.step(b.st);
        max_asleep = std::max(max_asleep, ea.sleeping());
      }
    };
    run(20000);
    for (Pile* p : {&a, &b}) add(p->st, {0.001, 0.002, 0.12}, {0.2, 0, -1}, kR);
    run(3000);
    dem::save_checkpoint(a.st, path);
    State c = dem::load_checkpoint(path);
    Pile cp = make_pile(threads, true);
    dem::Engine ec(cp.scene, kPileOptions);
    for (int k = 0; k < 3000; ++k) {
      ea.step(a.st);
      eb.step(b.st);
      ec.step(c);
    }
    EXPECT_GT(max_asleep, 50) << threads << " threads";
    for (const State* o : {&b.st, &c}) {
      ASSERT_EQ(a.st.size(), o->size());
      EXPECT_EQ(0, std::memcmp(a.st.x.data(), o->x.data(), a.st.size() * sizeof(Vec3)))
          << threads << " threads";
      EXPECT_EQ(0, std::memcmp(a.st.v.data(), o->v.data(), a.st.size() * sizeof(Vec3)));
      EXPECT_EQ(a.st.rest_steps, o->rest_steps);
    }
  }
}

// The pair loop reads a sleeper's row only when an awake particle is among its partners
// (Engine::pair_forces_impl); scanning every row as before must give the same bits, through a
// pile falling asleep and woken in part by two grains thrown onto it, on 1 and 2 threads.
TEST(dem_Sleep, SkippingTheRowsOfSleepersChangesNoBit) {
  for (int threads : {1, 2}) {
    Pile a = make_pile(threads, true), b = make_pile(threads, true);
    dem::EngineOptions every_row = kPileOptions;
    every_row.sleeper_row_skip = false;
    dem::Engine ea(a.scene, kPileOptions), eb(b.scene, every_row);
    std::int64_t mixed = 0;  // steps with sleepers and awake particles together
    auto run = [&](int steps) {
      for (int k = 0; k < steps; ++k) {
        ea.step(a.st);
        eb.step(b.st);
        mixed += ea.sleeping() > 0 && ea.sleeping() < static_cast<std::int64_t>(a.st.size());
      }
    };
    run(20000);
    for (Pile* p : {&a, &b}) add(p->st, {0.001, 0.002, 0.12}, {0.2, 0, -1}, kR);
    run(4000);
    for (Pile* p : {&a, &b}) add(p->st, {-0.004, 0.0, 0.1}, {0, 0.1, -1.5}, kR);
    run(4000);
    EXPECT_GT(mixed, 3000) << threads << " threads";
    EXPECT_EQ(0, std::memcmp(a.st.x.data(), b.st.x.data(), a.st.size() * sizeof(Vec3)))
        << threads << " threads";
    EXPECT_EQ(0, std::memcmp(a.st.v.data(), b.st.v.data(), a.st.size() * sizeof(Vec3)));
    ASSERT_EQ(a.st.pair_spring.size(), b.st.pair_spring.size());
    EXPECT_EQ(0, std::memcmp(a.st.pair_spring.data(), b.st.pair_spring.data(),
                             a.st.pair_spring.size() * sizeof(Vec3)));
    EXPECT_EQ(a.st.rest_steps, b.st.rest_steps);
  }
}

// A sleeper does not move, so the integration notes its displacement since the broad phase
// once, when it falls asleep, instead of every step (the Sleepers tally). The guard's two
// largest displacements must still cover every particle: equal to the ones counted over all
// particles until someone wakes (a woken one stays counted with the displacement it slept
// with, an upper bound, until the next broad phase), never below them. Through a pile falling
// asleep between broad phases (only when needed) and woken in part by a thrown grain.
TEST(dem_Sleep, SleepersCountInTheGuardsDisplacements) {
  for (int threads : {1, 2}) {
    Pile p = make_pile(threads, true);
    p.scene.broad_phase_interval = 1000000;
    dem::Engine e(p.scene, kPileOptions);
    std::int64_t checked = 0, equal = 0, led_by_sleeper = 0, woke = 0;
    std::int64_t rebuilds = -1;
    bool woken_since = false;
    std::vector<std::int32_t> rest_before;
    auto run = [&](int steps) {
      for (int k = 0; k < steps; ++k) {
        rest_before = p.st.rest_steps;
        e.step(p.st);
        if (p.st.rebuilds != rebuilds) {  // a broad phase this step: every displacement was 0
          rebuilds = p.st.rebuilds;
          woken_since = false;
        }
        double d1 = 0, d2 = 0, sleeper_max = 0, awake_max = 0;
        for (std::size_t i = 0; i < p.st.size(); ++i) {
          const double d = dem::norm(p.st.x[i] - p.st.x_at_rebuild[i]);
          if (d > d2) {
            d2 = std::min(d, d1);
            d1 = std::max(d, d1);
          }
          const bool sleeps = p.st.rest_steps[i] >= p.scene.sleep.steps;
          (sleeps ? sleeper_max : awake_max) = std::max(sleeps ? sleeper_max : awake_max, d);
          if (i < rest_before.size() && rest_before[i] >= p.scene.sleep.steps && !sleeps) {
            woken_since = true;
            ++woke;
          }
        }
        ++checked;
        EXPECT_GE(p.st.max_displacement, d1) << "step " << p.st.step << ", " << threads << " threads";
        EXPECT_GE(p.st.max_displacement + p.st.second_displacement, d1 + d2)
            << "step " << p.st.step << ", " << threads << " threads";
        if (!woken_since) {
          equal += p.st.max_displacement == d1 && p.st.second_displacement == d2;
          EXPECT_EQ(p.st.max_displacement, d1) << "step " << p.st.step;
          EXPECT_EQ(p.st.second_displacement, d2) << "step " << p.st.step;
        }
        led_by_sleeper += sleeper_max > 0 && sleeper_max > awake_max;
        if (::testing::Test::HasFailure()) return;
      }
    };
    run(20000);
    add(p.st, {0.001, 0.002, 0.12}, {0.2, 0, -1}, kR);
    run(4000);
    std::printf("%d threads: %lld steps checked, %lld equal, %lld led by a sleeper, %lld wakes\n",
                threads, static_cast<long long>(checked), static_cast<long long>(equal),
                static_cast<long long>(led_by_sleeper), static_cast<long long>(woke));
    // The test means something: sleepers moved before they slept and led the displacements,
    // and the thrown grain woke some.
    EXPECT_GT(led_by_sleeper, 100) << threads << " threads";
    EXPECT_GT(woke, 0) << threads << " threads";
    EXPECT_GT(equal, 1000) << threads << " threads";
  }
}

// The integration skips the tool-neighbourhood test for a block of 64 sleepers whose box is
// beyond every tool's neighbourhood, and a whole such block asleep and unwoken at once. Testing
// every sleeper as before must give the same bits: the sleeping pile with a plate swept over
// its top, turned, waking a strip of it (box and sphere neighbourhoods, 1 and 2 threads).
TEST(dem_Sleep, SkippingBlocksOfSleepersFarFromToolsChangesNoBit) {
  for (const auto shape : {dem::SleepNeighbourhood::box, dem::SleepNeighbourhood::sphere})
    for (int threads : {1, 2}) {
      const char* what = shape == dem::SleepNeighbourhood::box ? " box" : " sphere";
      Pile a = make_pile(threads, true), b = make_pile(threads, true);
      std::vector<Vec3> plate;
      quad(plate, {0, -0.005, 0}, {0.020, -0.005, 0}, {0.020, 0.005, 0}, {0, 0.005, 0});
      for (Pile* p : {&a, &b}) {
        p->scene.sleep.tool_distance = 0.004;
        p->scene.sleep.neighbourhood = shape;
        p->scene.tools.push_back(static_tool("plate", plate));
        p->st.tool_pose.resize(1);
        p->st.tool_pose[0].position = {1, 0, 1};
      }
      dem::EngineOptions every_sleeper = kPileOptions;
      every_sleeper.sleeper_blocks = false;
      dem::Engine ea(a.scene, kPileOptions), eb(b.scene, every_sleeper);
      auto step_both = [&] {
        ea.step(a.st);
        eb.step(b.st);
      };
      while (ea.sleeping() < 150 && a.st.step * a.scene.dt < 2.0) step_both();
      ASSERT_EQ(ea.sleeping(), 150) << what;
      double top = 0;
      for (const Vec3& x : a.st.x) top = std::max(top, x.z);
      std::int64_t woken = 0, quiet_block_steps = 0;
      const int sweep = 3000;
      for (int k = 0; k <= sweep; ++k) {
        // from x = -0.05 to 0.05 just over the top, its own x turned 60 degrees down
        for (Pile* p : {&a, &b}) {
          p->st.tool_pose[0].position = {-0.05 + 0.1 * k / sweep, 0.004, top + 0.012};
          p->st.tool_pose[0].orientation = {std::cos(M_PI / 6), 0, std::sin(M_PI / 6), 0};
        }
        step_both();
        woken = std::max<std::int64_t>(woken, 150 - ea.sleeping());
        // a block of 64 all asleep while the plate keeps others awake
        bool block_asleep = false;
        for (std::size_t b0 = 0; b0 + 64 <= a.st.size(); b0 += 64) {
          bool all = true;
          for (std::size_t i = b0; i < b0 + 64; ++i) all &= a.st.rest_steps[i] >= a.scene.sleep.steps;
          block_asleep |= all;
        }
        quiet_block_steps += block_asleep && ea.sleeping() < 150;
      }
      std::printf("%s, %d threads: up to %lld awake, %lld steps with a whole block asleep\n", what,
                  threads, static_cast<long long>(woken), static_cast<long long>(quiet_block_steps));
      EXPECT_GT(woken, 5) << what << threads;
      EXPECT_LT(woken, 140) << what << threads;
      EXPECT_GT(quiet_block_steps, 100) << what << threads;
      EXPECT_EQ(0, std::memcmp(a.st.x.data(), b.st.x.data(), a.st.size() * sizeof(Vec3))) << what << threads;
      EXPECT_EQ(0, std::memcmp(a.st.v.data(), b.st.v.data(), a.st.size() * sizeof(Vec3)));
      EXPECT_EQ(a.st.rest_steps, b.st.rest_steps) << what << threads;
    }
}

// The scene of the awake-list tests: the pile asleep, then a plate swept over its top (turned,
// waking a strip of it) while two grains are thrown onto it, so that sleepers wake by a tool,
// by a contact and fall asleep again, between broad phases and across them. step(k) is called
// before each step k with the states to pose.
struct Sweep {
  static constexpr int kSteps = 5000;
  static void setup(Pile& p) {
    std::vector<Vec3> plate;
    quad(plate, {0, -0.005, 0}, {0.020, -0.005, 0}, {0.020, 0.005, 0}, {0, 0.005, 0});
    p.scene.sleep.tool_distance = 0.004;
    p.scene.sleep.neighbourhood = dem::SleepNeighbourhood::box;
    p.scene.tools.push_back(static_tool("plate", plate));
    p.st.tool_pose.resize(1);
    p.st.tool_pose[0].position = {1, 0, 1};
  }
  // Before step k of the sweep (top: the pile's top once asleep).
  static void pose(State& st, int k, double top) {
    const int sweep = 2500;
    if (k < sweep) {
      st.tool_pose[0].position = {-0.05 + 0.1 * k / sweep, 0.004, top + 0.012};
      st.tool_pose[0].orientation = {std::cos(M_PI / 6), 0, std::sin(M_PI / 6), 0};
    } else {
      st.tool_pose[0].position = {1, 0, 1};
    }
    if (k == 500) add(st, {0.001, 0.002, top + 0.03}, {0.2, 0, -1}, kR);
    if (k == 2500) add(st, {-0.004, 0.0, top + 0.03}, {0, 0.1, -1.5}, kR);
  }
};

// The pile of make_pile asleep (made once, on 1 thread: pair blocks give every thread count the
// same bits), with the plate parked.
const State& asleep_pile() {
  static const State st = [] {
    Pile p = make_pile(1, true);
    Sweep::setup(p);
    p.scene.broad_phase_interval = 1000000;
    dem::Engine e(p.scene, kPileOptions);
    while (e.sleeping() < 150 && p.st.step * p.scene.dt < 2.0) e.step(p.st);
    return p.st;
  }();
  return st;
}
double top_of(const State& st) {
  double top = 0;
  for (const Vec3& x : st.x) top = std::max(top, x.z);
  return top;
}

bool same_bits(const State& a, const State& b) {
  return a.size() == b.size() &&
         std::memcmp(a.x.data(), b.x.data(), a.size() * sizeof(Vec3)) == 0 &&
         std::memcmp(a.v.data(), b.v.data(), a.size() * sizeof(Vec3)) == 0 &&
         std::memcmp(a.u.data(), b.u.data(), a.size() * sizeof(Vec3)) == 0 &&
         a.pair_spring.size() == b.pair_spring.size() &&
         std::memcmp(a.pair_spring.data(), b.pair_spring.data(),
                     a.pair_spring.size() * sizeof(Vec3)) == 0 &&
         a.rest_steps == b.rest_steps && a.id == b.id && a.rebuilds == b.rebuilds &&
         a.max_displacement == b.max_displacement &&
         a.second_displacement == b.second_displacement;
}

// The awake list (EngineOptions::awake_list): the pair loop starts the awake particles' forces
// only and the integration visits the awake particles and the sleepers a wake test needs. It
// must give the bits of the walk over every particle, step by step (positions, velocities,
// springs, rest counters, the guard's displacements, the sleeper count), on 1 and 2 threads,
// with pair blocks and with ranges (whose wakes beyond a thread's range are queued), and
// through a checkpoint: a run restored mid-sweep continues with the same bits.
TEST(dem_Sleep, AwakeListChangesNoBit) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "dem_awake_list_checkpoint.h5").string();
  for (const auto schedule : {dem::PairSchedule::blocks, dem::PairSchedule::ranges})
    for (int threads : {1, 2}) {
      const std::string what = std::string(schedule == dem::PairSchedule::blocks ? "blocks, " : "ranges, ") +
                               std::to_string(threads) + " threads";
      Pile a = make_pile(threads, true), b = make_pile(threads, true);
      for (Pile* p : {&a, &b}) {
        Sweep::setup(*p);
        p->scene.broad_phase_interval = 1000000;  // when needed: sleepers cross broad phases
        p->st = asleep_pile();
      }
      ASSERT_EQ(asleep(a.scene, a.st), 150);
      dem::EngineOptions listed = kPileOptions, walk = kPileOptions;
      listed.pair_schedule = walk.pair_schedule = schedule;
      walk.awake_list = false;
      dem::Engine ea(a.scene, listed), eb(b.scene, walk);
      const double top = top_of(a.st);
      std::int64_t mixed = 0, mismatch_at = -1;
      std::unique_ptr<Pile> c;
      std::unique_ptr<dem::Engine> ec;
      for (int k = 0; k < Sweep::kSteps; ++k) {
        if (k == 1500) {  // a checkpoint mid-sweep, continued by a third engine
          dem::save_checkpoint(a.st, path);
          c = std::make_unique<Pile>(make_pile(threads, true));
          Sweep::setup(*c);
          c->scene.broad_phase_interval = 1000000;
          c->st = dem::load_checkpoint(path);
          ec = std::make_unique<dem::Engine>(c->scene, listed);
        }
        for (State* st : {&a.st, &b.st}) Sweep::pose(*st, k, top);
        if (c) Sweep::pose(c->st, k, top);
        ea.step(a.st);
        eb.step(b.st);
        if (c) ec->step(c->st);
        mixed += ea.sleeping() > 0 && ea.sleeping() < static_cast<std::int64_t>(a.st.size());
        const bool same = same_bits(a.st, b.st) && ea.sleeping() == eb.sleeping() &&
                          (!c || (same_bits(a.st, c->st) && ea.sleeping() == ec->sleeping()));
        if (!same) {
          mismatch_at = k;
          break;
        }
      }
      std::printf("%s: %lld steps with sleepers and awake ones, woke %lld, fell asleep %lld, "
                  "%lld broad phases\n",
                  what.c_str(), static_cast<long long>(mixed),
                  static_cast<long long>(ea.woke_total()),
                  static_cast<long long>(ea.fell_asleep_total()),
                  static_cast<long long>(a.st.rebuilds));
      EXPECT_EQ(mismatch_at, -1) << what << ": the bits differ after step " << mismatch_at
                                 << " of the sweep";
      EXPECT_EQ(ea.woke_total(), eb.woke_total()) << what;
      // The test means something: wakes and sleeps beside each other for most of the sweep.
      EXPECT_GT(mixed, 2000) << what;
      EXPECT_GT(ea.woke_total(), 20) << what;
      EXPECT_GT(ea.fell_asleep_total(), 20) << what;
    }
  std::filesystem::remove(path);
}

// A sleeper's state is untouched while it sleeps: through the sweep, for every particle asleep
// before a step and after it, its position, velocity, u, radius and mass keep their bits (found
// by id across broad phases), and between broad phases the spring of every pair of two such
// sleepers keeps its bits (1 and 2 threads, the awake list on).
TEST(dem_Sleep, SleepersStateIsUntouchedWhileAsleep) {
  for (int threads : {1, 2}) {
    Pile p = make_pile(threads, true);
    Sweep::setup(p);
    p.scene.broad_phase_interval = 1000000;
    p.st = asleep_pile();
    dem::Engine e(p.scene, kPileOptions);
    const double top = top_of(p.st);
    const std::int32_t S = p.scene.sleep.steps;
    std::int64_t particle_checks = 0, spring_checks = 0, nonzero_springs = 0, bad = 0;
    for (int k = 0; k < Sweep::kSteps && bad == 0; ++k) {
      Sweep::pose(p.st, k, top);
      const State before = p.st;
      e.step(p.st);
      std::map<std::int64_t, std::size_t> at;  // id -> index after the step
      for (std::size_t i = 0; i < p.st.size(); ++i) at[p.st.id[i]] = i;
      std::vector<std::uint8_t> slept(before.size(), 0);  // asleep before and after, by old index
      for (std::size_t i = 0; i < before.size(); ++i) {
        const std::size_t j = at.at(before.id[i]);
        if (before.rest_steps[i] < S || p.st.rest_steps[j] < S) continue;
        slept[i] = 1;
        ++particle_checks;
        const bool same = std::memcmp(&before.x[i], &p.st.x[j], sizeof(Vec3)) == 0 &&
                          std::memcmp(&before.v[i], &p.st.v[j], sizeof(Vec3)) == 0 &&
                          std::memcmp(&before.u[i], &p.st.u[j], sizeof(Vec3)) == 0 &&
                          before.radius[i] == p.st.radius[j] && before.mass[i] == p.st.mass[j];
        if (!same) {
          ++bad;
          ADD_FAILURE() << "sleeper id " << before.id[i] << " changed in step " << k << ", "
                        << threads << " threads";
        }
      }
      // Pairs of two sleepers keep their springs (while the lists are the same lists).
      if (p.st.rebuilds == before.rebuilds && p.st.pair_j == before.pair_j) {
        for (std::size_t i = 0; i + 1 < before.pair_offset.size(); ++i)
          for (std::int32_t q = before.pair_offset[i]; q < before.pair_offset[i + 1]; ++q) {
            if (!slept[i] || !slept[static_cast<std::size_t>(before.pair_j[q])]) continue;
            ++spring_checks;
            nonzero_springs += dem::norm2(before.pair_spring[q]) > 0;
            if (std::memcmp(&before.pair_spring[q], &p.st.pair_spring[q], sizeof(Vec3)) != 0) {
              ++bad;
              ADD_FAILURE() << "spring of two sleepers changed in step " << k;
            }
          }
      }
    }
    std::printf("%d threads: %lld sleeper-steps and %lld sleeper-pair springs checked (%lld "
                "holding a spring)\n",
                threads, static_cast<long long>(particle_checks),
                static_cast<long long>(spring_checks), static_cast<long long>(nonzero_springs));
    EXPECT_EQ(bad, 0);
    EXPECT_GT(particle_checks, 50000) << threads << " threads";
    EXPECT_GT(nonzero_springs, 5000) << threads << " threads";
  }
}

TEST(dem_Region, RemovalKeepsListsAndHistoryOfTheRest) {
  Pile p = make_pile(1, false);
  dem::Engine e(p.scene, kPileOptions);
  while (p.st.step * p.scene.dt < 0.5) e.step(p.st);
  e.prepare(p.st);
  // Tangential springs by particle-id pair before the removal.
  auto springs = [](const State& st) {
    std::map<std::pair<std::int64_t, std::int64_t>, Vec3> out;
    for (std::size_t i = 0; i + 1 < st.pair_offset.size(); ++i)
      for (std::int32_t k = st.pair_offset[i]; k < st.pair_offset[i + 1]; ++k)
        out[{st.id[i], st.id[st.pair_j[k]]}] = st.pair_spring[k];
    return out;
  };
  const auto before = springs(p.st);
  std::vector<std::uint8_t> remove(p.st.size(), 0);
  double mass = 0;
  for (std::size_t i = 0; i < p.st.size(); ++i)
    if (p.st.id[i] % 7 == 3) {
      remove[i] = 1;
      mass += p.st.mass[i];
    }
  const std::size_t n_removed = dem::remove_particles(p.st, remove);
  EXPECT_EQ(n_removed, 21u);  // ids 3, 10, ..., 143
  EXPECT_EQ(p.st.size(), 129u);
  EXPECT_EQ(p.st.removed_count, 21);
  EXPECT_EQ(p.st.removed_mass, mass);
  const auto after = springs(p.st);
  std::size_t kept = 0, nonzero = 0;
  for (const auto& [ids, spring] : before) {
    const bool gone = ids.first % 7 == 3 || ids.second % 7 == 3;
    const auto it = after.find(ids);
    if (gone) {
      EXPECT_TRUE(it == after.end());
      continue;
    }
    ASSERT_TRUE(it != after.end());
    EXPECT_EQ(0, std::memcmp(&it->second, &spring, sizeof(Vec3)));
    ++kept;
    nonzero += norm(spring) > 0;
  }
  EXPECT_EQ(kept, after.size());
  EXPECT_GT(nonzero, 50u);
  for (std::size_t i = 0; i < p.st.size(); ++i) EXPECT_NE(p.st.id[i] % 7, 3);
  // Every per-particle array has the new size; the lists match a brute-force search.
  dem::for_each_array(p.st, [&](const char* name, const auto& a, dem::Field f) {
    if (f != dem::Field::derived && !(f == dem::Field::model && a.empty())) {
      EXPECT_EQ(a.size(), 129u) << name;
    }
  });
  EXPECT_EQ(p.st.x_at_rebuild.size(), 129u);
  EXPECT_EQ(p.st.wall_mask.size(), 129u);
  std::vector<std::pair<std::int64_t, std::int64_t>> brute;
  for (std::size_t i = 0; i < p.st.size(); ++i)
    for (std::size_t j = i + 1; j < p.st.size(); ++j) {
      const double rs = p.st.radius[i] + p.st.radius[j];
      if (norm2(p.st.x[i] - p.st.x[j]) < rs * rs)
        brute.emplace_back(std::min(p.st.id[i], p.st.id[j]), std::max(p.st.id[i], p.st.id[j]));
    }
  std::sort(brute.begin(), brute.end());
  EXPECT_EQ(e.particle_contacts(p.st), brute);
  for (int k = 0; k < 100; ++k) e.step(p.st);  // and the run continues
}

TEST(dem_Region, ParticlesLeavingTheBoxAreRemovedAndCounted) {
  Pile p = make_pile(1, false);
  p.scene.region = {true, {-0.1, -0.1, -0.01}, {0.1, 0.1, 0.2}};
  // Two strays: one thrown up out of the top, one sideways out of x.
  add(p.st, {0.0, 0.0, 0.15}, {0, 0, 3}, kR);
  add(p.st, {0.05, 0.0, 0.1}, {2, 0, 0}, 0.8 * kR);
  const double m_out = sphere_mass(kR) + sphere_mass(0.8 * kR);
  dem::Engine e(p.scene, kPileOptions);
  while (p.st.step * p.scene.dt < 0.1) e.step(p.st);
  EXPECT_EQ(p.st.size(), 150u);
  EXPECT_EQ(p.st.removed_count, 2);
  EXPECT_NEAR(p.st.removed_mass, m_out, 1e-15);
  EXPECT_EQ(index_of(p.st, 150), p.st.size());
  EXPECT_EQ(index_of(p.st, 151), p.st.size());
}

std::string load_error(const std::vector<std::string>& sets) {
  const char* base = R"(
scene: {dt: 1.0e-5, threads: 1}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact:
  particle_particle: {normal_stiffness: 4.0e7, restitution: 0.3, friction: 0.5}
particles:
  list:
    - {species: grain, position: [0, 0, 0.1]}
)";
  try {
    YAML::Node root = YAML::Load(base);
    for (const auto& s : sets) cosim::config::apply_override(root, s);
    dem::load_config(root, std::filesystem::temp_directory_path().string());
    return "";
  } catch (const std::exception& e) {
    return e.what();
  }
}

TEST(dem_Sleep, BadValuesRefusedNamingTheKey) {
  EXPECT_EQ(load_error({"scene.sleep={enabled: true, speed: 0.001, steps: 100, tool_distance: 0.1}"}),
            "");
  EXPECT_EQ(load_error({"scene.sleep={enabled: true, speed: 0.01, wake_speed: 0.002, steps: 300}"}), "");
  EXPECT_EQ(load_error({"scene.region={min: [-1, -1, -1], max: [1, 1, 1]}"}), "");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"scene.sleep.speed=0", "scene.sleep.speed"},
      {"scene.sleep.speed=-1", "scene.sleep.speed"},
      {"scene.sleep.wake_speed=0", "scene.sleep.wake_speed"},
      {"scene.sleep.wake_speed=-0.001", "scene.sleep.wake_speed"},
      {"scene.sleep.wake_speed=0.02", "scene.sleep.wake_speed"},  // above speed (0.01)
      {"scene.sleep.wake_speed=fast", "scene.sleep.wake_speed"},
      {"scene.sleep.steps=0", "scene.sleep.steps"},
      {"scene.sleep.steps=2.5", "scene.sleep.steps"},
      {"scene.sleep.tool_distance=-0.1", "scene.sleep.tool_distance"},
      {"scene.sleep.neighbourhood=cube", "scene.sleep.neighbourhood"},
      {"scene.sleep.enabled=maybe", "scene.sleep.enabled"},
      {"scene.sleep.sped=0.1", "speed"},  // did you mean
      {"scene.sleep=3", "scene.sleep"},
      // dt 1e-5 s: a thrown particle is slower than 0.01 m/s for 204 steps around its apex
      {"scene.sleep={enabled: true, speed: 0.01, steps: 100}", "scene.sleep.steps"},
      {"scene.region={min: [1, -1, -1], max: [0, 1, 1]}", "scene.region"},
      {"scene.region={min: [0, 0, 0]}", "scene.region"},
      {"scene.region={min: [0, 0], max: [1, 1, 1]}", "scene.region.min"},
  };
  for (const auto& [set, key] : cases) {
    const std::string msg = load_error({set});
    EXPECT_NE(msg.find(key), std::string::npos) << set << " -> '" << msg << "'";
  }
  const std::string apex = load_error({"scene.sleep={enabled: true, speed: 0.01, steps: 100}"});
  EXPECT_NE(apex.find("above 203"), std::string::npos) << apex;
}

}  // namespace
