// Sleeping (scene.sleep) with the rotating particle model (dem/rotation.hpp): a pile of rotating
// grains with rolling resistance falls asleep with no translational or rotational energy left,
// every sleeper keeps the bits of x, v, u, w, wu and of the tangential and rolling springs it
// shares with other sleepers while asleep, a grain dropped on the pile wakes it and it falls
// asleep again; sleep that never triggers gives the bits of sleep disabled (1 and 2 threads);
// runs with sleepers continue bit for bit through a checkpoint, on 1 and 2 threads.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <map>
#include <random>

#include "dem/checkpoint.hpp"
#include "dem/rotation.hpp"
#include "dem_test_util.hpp"

namespace {

using namespace demtest;
using dem::State;

constexpr double kR = 0.005;
constexpr double kK = 2e4;  // N/m
constexpr double kG = 9.81;

struct Pile {
  dem::Scene scene;
  State st;
};

const dem::EngineOptions kOptions = [] {
  dem::EngineOptions o;
  o.min_particles_per_thread = 1;  // a small scene on every thread it is given
  return o;
}();

// 150 rotating grains (radius 4-5 mm, friction 0.5, EPSD rolling resistance mu_r 0.1) dropped
// from a jittered lattice onto a floor.
Pile make_pile(int threads, bool sleep) {
  Pile p;
  p.scene = one_species_scene(0.8 * kR, kR);
  p.scene.gravity = {0, 0, -kG};
  p.scene.threads = threads;
  p.scene.particle_particle = p.scene.particle_wall = law_n_per_m(kK, 0.3, true, 0.5, 1.0, 0.5);
  p.scene.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}});
  p.scene.rotation.model = dem::ParticleModel::rotating;
  p.scene.rotation.rolling.kind = dem::RollingResistance::Kind::epsd;
  p.scene.rotation.rolling.friction = 0.1;
  p.scene.rotation.rolling.damping = 0.3;
  // The tangential period with free spins is shorter than the normal one (docs/soil_models.md).
  p.scene.dt = M_PI / std::sqrt(kK / sphere_mass(0.8 * kR)) / 40;
  p.scene.sleep.enabled = sleep;
  p.scene.sleep.speed = 0.005;
  p.scene.sleep.steps = 200;
  add_jittered_block(p.st, kR, 11);
  return p;
}

std::int64_t asleep(const dem::Scene& sc, const State& st) {
  std::int64_t n = 0;
  for (const std::int32_t r : st.rest_steps) n += r >= sc.sleep.steps;
  return n;
}

bool same(const void* a, const void* b, std::size_t bytes) { return std::memcmp(a, b, bytes) == 0; }

// Everything a step changes, bit for bit (the rotating model's arrays included).
std::string differ(const State& a, const State& b) {
  if (a.size() != b.size()) return "size";
  const std::size_t n = a.size() * sizeof(Vec3);
  if (!same(a.x.data(), b.x.data(), n)) return "x";
  if (!same(a.v.data(), b.v.data(), n)) return "v";
  if (!same(a.u.data(), b.u.data(), n)) return "u";
  if (a.w.size() != a.size() || b.w.size() != b.size()) return "w size";
  if (!same(a.w.data(), b.w.data(), n)) return "w";
  if (!same(a.wu.data(), b.wu.data(), n)) return "wu";
  if (a.pair_spring.size() != b.pair_spring.size() ||
      !same(a.pair_spring.data(), b.pair_spring.data(), a.pair_spring.size() * sizeof(Vec3)))
    return "pair_spring";
  if (a.pair_roll.size() != b.pair_roll.size() ||
      !same(a.pair_roll.data(), b.pair_roll.data(), a.pair_roll.size() * sizeof(Vec3)))
    return "pair_roll";
  if (a.rest_steps != b.rest_steps) return "rest_steps";
  if (a.id != b.id) return "id";
  return "";
}

// The pile asleep (made once, 1 thread).
const State& asleep_pile() {
  static const State st = [] {
    Pile p = make_pile(1, true);
    dem::Engine e(p.scene, kOptions);
    while (e.sleeping() < 150 && p.st.step * p.scene.dt < 3.0) e.step(p.st);
    return p.st;
  }();
  return st;
}

// Steps the engine once and checks that every particle asleep before and after the step kept
// x, v, u, w, wu (by id, across broad phases) and that every pair of two such sleepers kept its
// tangential and rolling springs (while the lists are the same). Returns the failures.
struct Checks {
  std::int64_t particles = 0, pairs = 0, rolling = 0, bad = 0;
};
void step_checking_sleepers(dem::Engine& e, const dem::Scene& sc, State& st, Checks& c) {
  const State before = st;
  e.step(st);
  const std::int32_t S = sc.sleep.steps;
  std::map<std::int64_t, std::size_t> at;
  for (std::size_t i = 0; i < st.size(); ++i) at[st.id[i]] = i;
  std::vector<std::uint8_t> slept(before.size(), 0);
  for (std::size_t i = 0; i < before.size(); ++i) {
    const auto it = at.find(before.id[i]);
    if (it == at.end()) continue;
    const std::size_t j = it->second;
    if (before.rest_steps[i] < S || st.rest_steps[j] < S) continue;
    slept[i] = 1;
    ++c.particles;
    const bool kept = same(&before.x[i], &st.x[j], sizeof(Vec3)) &&
                      same(&before.v[i], &st.v[j], sizeof(Vec3)) &&
                      same(&before.u[i], &st.u[j], sizeof(Vec3)) &&
                      same(&before.w[i], &st.w[j], sizeof(Vec3)) &&
                      same(&before.wu[i], &st.wu[j], sizeof(Vec3));
    if (!kept) {
      ++c.bad;
      ADD_FAILURE() << "sleeper id " << before.id[i] << " changed in step " << before.step;
    }
    if (dem::norm2(st.w[j]) != 0 || dem::norm2(st.v[j]) != 0) {
      ++c.bad;
      ADD_FAILURE() << "sleeper id " << before.id[i] << " moves or turns";
    }
  }
  if (st.rebuilds == before.rebuilds && st.pair_j == before.pair_j) {
    for (std::size_t i = 0; i + 1 < before.pair_offset.size(); ++i)
      for (std::int32_t q = before.pair_offset[i]; q < before.pair_offset[i + 1]; ++q) {
        if (!slept[i] || !slept[static_cast<std::size_t>(before.pair_j[q])]) continue;
        ++c.pairs;
        c.rolling += dem::nonzero(before.pair_roll[q]);
        if (!same(&before.pair_spring[q], &st.pair_spring[q], sizeof(Vec3)) ||
            !same(&before.pair_roll[q], &st.pair_roll[q], sizeof(Vec3))) {
          ++c.bad;
          ADD_FAILURE() << "a spring of two sleepers changed in step " << before.step;
        }
      }
  }
}

TEST(dem_SleepRotating, PileFallsAsleepStaysStillAndWakesWhenHit) {
  Pile p = make_pile(1, true);
  p.st = asleep_pile();
  const double t_asleep = p.st.step * p.scene.dt;
  ASSERT_EQ(asleep(p.scene, p.st), 150) << "not all asleep after " << t_asleep << " s";
  std::printf("rotating pile: all 150 asleep at %.3f s\n", t_asleep);
  EXPECT_EQ(dem::kinetic_energy(p.st), 0.0);
  EXPECT_EQ(dem::rotational_energy(p.st), 0.0);
  std::int64_t rolling_springs = 0;
  for (const Vec3& r : p.st.pair_roll) rolling_springs += dem::nonzero(r);
  EXPECT_GT(rolling_springs, 50) << "the sleepers' rolling springs should be held";

  // Asleep: 2000 steps change no bit (x, v, w, springs), nothing wakes.
  dem::Engine e(p.scene, kOptions);
  const State still = p.st;
  Checks c;
  for (int k = 0; k < 2000; ++k) step_checking_sleepers(e, p.scene, p.st, c);
  EXPECT_EQ(c.bad, 0);
  EXPECT_EQ(e.sleeping(), 150);
  EXPECT_EQ(e.woke_total(), 0);
  EXPECT_EQ(differ(still, p.st), "") << "a pile asleep changed";

  // A grain dropped onto the pile at 1 m/s wakes part of it; all settle asleep again, and the
  // sleepers keep their bits throughout.
  double top = 0;
  for (const Vec3& x : p.st.x) top = std::max(top, x.z);
  add(p.st, {0.001, 0.002, top + 0.03}, {0.1, 0, -1}, kR);
  std::int64_t fewest = 151;
  const double t0 = p.st.step * p.scene.dt;
  while (p.st.step * p.scene.dt < t0 + 3.0) {
    step_checking_sleepers(e, p.scene, p.st, c);
    fewest = std::min(fewest, e.sleeping());
    if (e.sleeping() == 151) break;
  }
  std::printf("the drop: fewest asleep %lld of 151, woke %lld, fell asleep %lld, all asleep "
              "again after %.3f s; %lld sleeper-steps, %lld sleeper pairs (%lld with a rolling "
              "spring) checked\n",
              static_cast<long long>(fewest), static_cast<long long>(e.woke_total()),
              static_cast<long long>(e.fell_asleep_total()), p.st.step * p.scene.dt - t0,
              static_cast<long long>(c.particles), static_cast<long long>(c.pairs),
              static_cast<long long>(c.rolling));
  EXPECT_EQ(c.bad, 0);
  EXPECT_GT(e.woke_total(), 5) << "the drop should wake the grains it hits";
  EXPECT_LT(fewest, 140);
  EXPECT_EQ(e.sleeping(), 151) << "the pile should settle asleep again";
  EXPECT_EQ(dem::rotational_energy(p.st), 0.0);
  EXPECT_GT(c.rolling, 10000) << "the check should see the sleepers' rolling springs";
}

// Sleep enabled with a speed nobody gets below: the bits of sleep disabled (1 and 2 threads).
TEST(dem_SleepRotating, SleepThatNeverTriggersIsBitIdenticalToDisabled) {
  for (int threads : {1, 2}) {
    Pile a = make_pile(threads, false), b = make_pile(threads, true);
    b.scene.sleep.speed = 1e-300;
    dem::Engine ea(a.scene, kOptions), eb(b.scene, kOptions);
    for (int k = 0; k < 3000; ++k) {
      ea.step(a.st);
      eb.step(b.st);
    }
    EXPECT_EQ(eb.sleeping(), 0);
    EXPECT_EQ(eb.threads(), threads);
    b.st.rest_steps = a.st.rest_steps;  // (rest counters exist with sleep only)
    EXPECT_EQ(differ(a.st, b.st), "") << threads << " threads";
    EXPECT_GT(dem::rotational_energy(a.st), 0.0) << "the grains should turn";
    EXPECT_EQ(0, std::memcmp(&ea.wall_forces()[0], &eb.wall_forces()[0], sizeof(Vec3)));
  }
}

// A grain dropped into the asleep pile; the run saved mid-way with sleepers and awake grains
// continues bit for bit after a reload, on 1 and 2 threads, and 2 threads give the bits of 1.
TEST(dem_SleepRotating, CheckpointWithSleepersContinuesBitForBit) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "dem_rotation_sleep_checkpoint.h5").string();
  State one;
  for (int threads : {1, 2}) {
    Pile a = make_pile(threads, true);
    a.st = asleep_pile();
    ASSERT_EQ(asleep(a.scene, a.st), 150);
    add(a.st, {0.001, 0.002, 0.08}, {0.1, 0, -1}, kR);
    dem::Engine ea(a.scene, kOptions);
    for (int k = 0; k < 1500; ++k) ea.step(a.st);
    const std::int64_t sleepers = ea.sleeping();
    EXPECT_GT(sleepers, 10) << threads << " threads";
    EXPECT_LT(sleepers, 151) << threads << " threads: some should be awake at the save";
    dem::save_checkpoint(a.st, path);
    State c = dem::load_checkpoint(path);
    EXPECT_EQ(dem::differing_arrays(a.st, c), "");
    dem::Engine ec(a.scene, kOptions);
    std::int64_t mixed = 0;
    for (int k = 0; k < 3000; ++k) {
      ea.step(a.st);
      ec.step(c);
      mixed += ea.sleeping() > 0 && ea.sleeping() < 151;
    }
    EXPECT_EQ(ec.threads(), threads);
    EXPECT_EQ(differ(a.st, c), "") << threads << " threads";
    EXPECT_EQ(ea.sleeping(), ec.sleeping());
    EXPECT_GT(mixed, 500) << threads << " threads: sleepers beside awake grains";
    if (threads == 1)
      one = a.st;
    else
      EXPECT_EQ(differ(one, a.st), "") << "2 threads against 1";
  }
  std::filesystem::remove(path);
}

}  // namespace
