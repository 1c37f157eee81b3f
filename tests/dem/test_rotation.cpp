// The rotating particle model (dem/rotation.hpp) against closed forms: rolling down an incline at
// 5/7 g sin(theta), rolling to a stop under a rolling-resistance torque mu_r R F_n, the torque a
// turning box feels from a packing it turns (against the load's weight and angular momentum),
// checkpoints that restart bit for bit, the default model unchanged, and bad input refused by name.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <map>
#include <filesystem>
#include <sstream>

#include "cosim/yaml_config.hpp"
#include "dem/checkpoint.hpp"
#include "dem/config.hpp"
#include "dem/rotation.hpp"
#include "dem/stability.hpp"
#include "dem_test_util.hpp"

namespace {

using namespace demtest;
using dem::State;

constexpr double kR = 0.01;
constexpr double kG = 9.81;

dem::Scene rotating_scene(double mu, double mu_r) {
  dem::Scene scene = one_species_scene(kR, kR);
  scene.gravity = {0, 0, -kG};
  scene.particle_particle = scene.particle_wall = law_n_per_m(2e4, 0.3, true, mu, 0.5, 0.5);
  scene.rotation.model = dem::ParticleModel::rotating;
  if (mu_r > 0) {
    scene.rotation.rolling.kind = dem::RollingResistance::Kind::epsd;
    scene.rotation.rolling.friction = mu_r;
  }
  const double m = sphere_mass(kR);
  scene.dt = M_PI / std::sqrt(2e4 / m) / 50;
  return scene;
}

// A sphere starting at rest on an incline of angle theta (analytic wall or a triangle mesh split
// along its diagonal) with friction enough to roll (mu > 2/7 tan theta): the centre accelerates
// at a = g sin(theta) / (1 + I / (m r^2)) = 5/7 g sin(theta), and w r = v (no slip).
struct Rolled {
  double accel, slip;
};
Rolled roll_down(double theta, bool mesh, dem::ParticleModel model) {
  dem::Scene scene = rotating_scene(0.5, 0);
  scene.rotation.model = model;
  const Vec3 n{std::sin(theta), 0, std::cos(theta)};
  const Vec3 down{std::cos(theta), 0, -std::sin(theta)};
  if (mesh) {
    const double L = 2.0, W = 0.05;
    const Vec3 across{0, 1, 0};
    const Vec3 o = (-0.2) * down + (-W / 2) * across;
    const Vec3 a = o, b = o + L * down, c = o + L * down + W * across, d = o + W * across;
    scene.tools.push_back(static_tool("incline", {a, b, c, a, c, d}));
  } else {
    scene.walls.push_back({"incline", {0, 0, 0}, n});
  }
  const double m = sphere_mass(kR);
  State st;
  add(st, (kR - m * kG * std::cos(theta) / 2e4) * n, {}, kR);
  st.tool_pose.resize(scene.tools.size());
  dem::Engine engine(scene);
  auto along = [&] { return dot(st.x[0], down); };
  while (st.step * scene.dt < 0.1) engine.step(st);
  const double t1 = st.step * scene.dt, s1 = along(), v1 = dot(st.v[0], down);
  while (st.step * scene.dt < 0.4) engine.step(st);
  const double T = st.step * scene.dt - t1;
  Rolled r;
  r.accel = 2 * (along() - s1 - v1 * T) / (T * T);
  // The spin about the axis across the slope, as a speed at the rim, against the centre's speed.
  const double v = dot(st.v[0], down);
  r.slip = st.w.empty() ? v : v - kR * st.w[0].y;
  return r;
}

TEST(dem_Rotation, RollsDownAnInclineAtFiveSeventhsOfGSinTheta) {
  for (const bool mesh : {false, true})
    for (const double deg : {10.0, 25.0}) {
      const double th = deg * M_PI / 180;
      const Rolled r = roll_down(th, mesh, dem::ParticleModel::rotating);
      const double want = 5.0 / 7.0 * kG * std::sin(th);
      std::printf("%s incline %4.1f deg: a = %.5f m/s^2, 5/7 g sin = %.5f (%.3f %%), slip %.2e m/s\n",
                  mesh ? "mesh" : "wall", deg, r.accel, want, 100 * (r.accel / want - 1), r.slip);
      // 1 %: a 2/5 vs 5/7 mix-up (I = m r^2: 1/2 g sin) or a missing spin (g sin) is 30 % off.
      EXPECT_NEAR(r.accel / want, 1.0, 0.01) << (mesh ? "mesh" : "wall") << " " << deg << " deg";
      EXPECT_LT(std::abs(r.slip), 1e-3 * want) << "rolls without slipping";
    }
  // The translating model's sphere cannot roll: with mu = 0.5 > tan(25 deg) it stays put.
  const Rolled t = roll_down(25 * M_PI / 180, false, dem::ParticleModel::translating);
  EXPECT_LT(std::abs(t.accel), 1e-3);
}

// Rolling on a floor with the EPSD rolling resistance, whose spring is fully mobilised (the
// constant torque mu_r R F_n against the rolling) after turning through mu_r R F_n / k_r, a few
// milliradians: the centre decelerates at a = mu_r R m g / (R m (1 + 2/5)) = 5/7 mu_r g and stops
// after v0^2 / (2a) = 7 v0^2 / (10 mu_r g).
TEST(dem_Rotation, RollingResistanceStopsARollingSphereAtTheClosedForm) {
  for (const double mu_r : {0.05, 0.2}) {
    dem::Scene scene = rotating_scene(0.5, mu_r);
    scene.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}});
    const double m = sphere_mass(kR), v0 = 0.4;
    State st;
    add(st, {0, 0, kR - m * kG / 2e4}, {v0, 0, 0}, kR);
    dem::Engine engine(scene);
    dem::Rotation::size_arrays(st);
    st.w[0] = st.wu[0] = {0, v0 / kR, 0};  // rolling: w x (-R e_z) = v0 e_x
    const double a = 5.0 / 7.0 * mu_r * kG;
    const double stop_time = v0 / a, stop = 7 * v0 * v0 / (10 * mu_r * kG);
    // The deceleration over the middle of the run.
    while (st.step * scene.dt < 0.2 * stop_time) engine.step(st);
    const double t1 = st.step * scene.dt, v1 = st.v[0].x;
    while (st.step * scene.dt < 0.8 * stop_time) engine.step(st);
    const double decel = (v1 - st.v[0].x) / (st.step * scene.dt - t1);
    // Where it stops: the first step its speed changes sign (after that the spring rocks it
    // elastically through micrometres).
    double x_stop = 0;
    while (st.step * scene.dt < 2 * stop_time) {
      engine.step(st);
      if (st.v[0].x <= 0) {
        x_stop = st.x[0].x;
        break;
      }
    }
    std::printf("mu_r %.2f: deceleration %.5f (5/7 mu_r g = %.5f, %.3f %%), stops at %.5f m "
                "(7 v0^2/(10 mu_r g) = %.5f, %.3f %%)\n",
                mu_r, decel, a, 100 * (decel / a - 1), x_stop, stop, 100 * (x_stop / stop - 1));
    EXPECT_NEAR(decel / a, 1.0, 0.01) << "mu_r " << mu_r;
    EXPECT_NEAR(x_stop / stop, 1.0, 0.01) << "mu_r " << mu_r;
    // Stopped, it stays: run on and it has not crept.
    for (int k = 0; k < 2000; ++k) engine.step(st);
    EXPECT_NEAR(st.x[0].x, x_stop, 1e-3 * stop);
  }
}

// ---- A closed box (12 triangles) turning at a constant rate about a horizontal hinge with a
// packing inside. The torque the grains put on the box about the hinge, summed over the turn,
// against what the load's weight and angular momentum give: sum_n [sum_i (x_i - p) x m_i g] -
// (L_end - L_start) / dt, with L = sum_i m_i (x_i - p) x v_i + I_i w_i. With rotation every
// contact gives both grains (and the box) the moments of one force at one point, and the two
// agree; without it the tangential forces between grains sliding past each other (a packing
// that turns as a whole makes every contact slide when the grains cannot spin) put an extra
// torque on the box.

constexpr double kBox[3] = {0.12, 0.08, 0.08};  // inner size, hinge along y at the box's x = -0.02
constexpr double kHinge = 0.02;

std::vector<Vec3> box_triangles() {
  const double x0 = kHinge, x1 = kHinge + kBox[0], y0 = -kBox[1] / 2, y1 = kBox[1] / 2, z0 = 0,
               z1 = kBox[2];
  const Vec3 c[8] = {{x0, y0, z0}, {x1, y0, z0}, {x1, y1, z0}, {x0, y1, z0},
                     {x0, y0, z1}, {x1, y0, z1}, {x1, y1, z1}, {x0, y1, z1}};
  const int f[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4}, {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 2, 6, 5}};
  std::vector<Vec3> t;
  for (const auto& q : f) t.insert(t.end(), {c[q[0]], c[q[1]], c[q[2]], c[q[0]], c[q[2]], c[q[3]]});
  return t;
}

dem::Scene box_scene(bool rotating) {
  dem::Scene scene = one_species_scene(0.0045, 0.0055);
  scene.gravity = {0, 0, -kG};
  scene.particle_particle = scene.particle_wall = law_n_per_m(1e4, 0.3, true, 0.5, 0.5, 0.5);
  scene.dt = 2.5e-5;
  scene.tools.push_back(static_tool("box", box_triangles()));
  if (rotating) {
    scene.rotation.model = dem::ParticleModel::rotating;
    scene.rotation.rolling.kind = dem::RollingResistance::Kind::epsd;
    scene.rotation.rolling.friction = 0.1;
    scene.rotation.rolling.damping = 0.3;
  }
  return scene;
}

// The packing (translating model, box at rest, 0.2 s): 300 grains dropped from a jittered
// lattice of 5 layers.
const State& settled_box() {
  static State st = [] {
    dem::Scene scene = box_scene(false);
    State s;
    std::uint64_t h = 7;
    const double step = 0.0116;
    for (int k = 0; k < 5; ++k)
      for (int j = 0; j < 6; ++j)
        for (int i = 0; i < 10; ++i) {
          h = h * 6364136223846793005ull + 1442695040888963407ull;
          const double r = 0.0045 + 0.001 * static_cast<double>(h >> 11) * 0x1.0p-53;
          // Jittered sideways by up to 2 mm, so the columns collapse into a random packing.
          auto jitter = [&h] {
            h = h * 6364136223846793005ull + 1442695040888963407ull;
            return 0.004 * (static_cast<double>(h >> 11) * 0x1.0p-53 - 0.5);
          };
          const double dx = jitter(), dy = jitter();
          add(s, {kHinge + 0.006 + step * i + dx, -kBox[1] / 2 + 0.006 + step * j + dy,
                  0.006 + step * k},
              {}, r);
        }
    s.tool_pose.resize(1);
    dem::Engine engine(scene);
    for (int k = 0; k < 8000; ++k) engine.step(s);
    return s;
  }();
  return st;
}

struct TurnTorque {
  double measured, expected;  // about the hinge (y), summed over the steps of the turn
};

TurnTorque turn_box(bool rotating) {
  dem::Scene scene = box_scene(rotating);
  State st = settled_box();
  const double omega = -1.0;  // rad/s about +y: the far end (x > 0) rises, as a tipping body
  auto pose = [&](double t) {
    const double a = omega * t;
    dem::ToolPose p;
    p.orientation = {std::cos(a / 2), 0, std::sin(a / 2), 0};
    p.angular_velocity = {0, omega, 0};
    return p;
  };
  const std::int64_t start = st.step;
  auto momentum = [&] {
    Vec3 L{};
    for (std::size_t i = 0; i < st.size(); ++i) {
      L += st.mass[i] * cross(st.x[i], st.v[i]);  // the hinge is the origin
      if (!st.w.empty()) L += dem::moment_of_inertia(st.mass[i], st.radius[i]) * st.w[i];
    }
    return L;
  };
  dem::Engine engine(scene);
  // The box spins up in one step and turns through 0.3 rad; the sums skip the first 0.02 s.
  const int steps = static_cast<int>(0.3 / std::abs(omega) / scene.dt), skip = 800;
  TurnTorque r{0, 0};
  Vec3 L0{};
  for (int k = 0; k < steps; ++k) {
    if (k == skip) L0 = momentum();
    Vec3 weight{};
    for (std::size_t i = 0; i < st.size(); ++i) weight += cross(st.x[i], st.mass[i] * scene.gravity);
    st.tool_pose[0] = pose(static_cast<double>(st.step - start) * scene.dt);
    engine.step(st);
    if (k >= skip) {
      r.measured += engine.tool_wrenches()[0].torque.y;
      r.expected += weight.y;
    }
  }
  r.expected -= (momentum() - L0).y / scene.dt;
  return r;
}

TEST(dem_Rotation, TurningBoxFeelsOnlyTheLoadsWeightAndMomentumWithRotation) {
  const TurnTorque rot = turn_box(true), tra = turn_box(false);
  const double e_rot = rot.measured / rot.expected - 1, e_tra = tra.measured / tra.expected - 1;
  std::printf("turning box, torque about the hinge over the turn against weight + momentum: "
              "rotating %.4f %%, translating %.4f %% (sums %.6g vs %.6g and %.6g vs %.6g N m steps)\n",
              100 * e_rot, 100 * e_tra, rot.measured, rot.expected, tra.measured, tra.expected);
  EXPECT_LT(std::abs(e_rot), 0.02);
  EXPECT_GT(std::abs(e_tra), 3 * std::abs(e_rot));
  EXPECT_GT(std::abs(e_tra), 0.02) << "the translating model's artefact";
}

// ---- Checkpoints: a rotating bed in motion (spins, tangential and rolling springs at pairs and
// walls) saved and restored continues bit for bit, across broad phases.
TEST(dem_Rotation, CheckpointRestartsBitForBit) {
  dem::Scene scene = box_scene(true);
  State st = settled_box();
  st.tool_pose[0] = dem::ToolPose{};
  st.tool_pose[0].angular_velocity = {0, 0, 0};
  for (std::size_t i = 0; i < st.size(); ++i) st.v[i] = st.u[i] = {0.05, 0, 0.02};  // stir it
  dem::Engine a(scene);
  for (int k = 0; k < 503; ++k) a.step(st);
  ASSERT_EQ(st.w.size(), st.size());
  ASSERT_FALSE(st.pair_roll.empty());
  ASSERT_FALSE(st.slot_roll.empty());
  bool spinning = false, rolling = false;
  for (const Vec3& w : st.w) spinning |= norm(w) > 1e-3;
  for (const Vec3& r : st.pair_roll) rolling |= nonzero(r);
  EXPECT_TRUE(spinning);
  EXPECT_TRUE(rolling);
  const std::string path =
      (std::filesystem::temp_directory_path() / "dem_rotation_checkpoint.h5").string();
  dem::save_checkpoint(st, path);
  State back = dem::load_checkpoint(path);
  EXPECT_EQ(dem::differing_arrays(st, back), "");
  // Two threads (the boundary chunks and the integration split; the pair loop is one thread)
  // give the same bits as one.
  dem::Scene two = scene;
  two.threads = 2;
  dem::EngineOptions options;
  options.min_particles_per_thread = 1;  // a small scene on every thread it is given
  State on_two = dem::load_checkpoint(path);
  dem::Engine b(scene), c(two, options);
  for (int k = 0; k < 120; ++k) {  // 24 broad phases
    a.step(st);
    b.step(back);
    c.step(on_two);
  }
  EXPECT_EQ(c.threads(), 2);
  EXPECT_EQ(dem::differing_arrays(st, back), "");
  EXPECT_EQ(dem::differing_arrays(st, on_two), "");
  std::filesystem::remove(path);
}

// ---- The rolling springs go with their contacts through broad phases (sorting, new lists):
// every pair's (by ids, as the torque on the lower id) and every wall and mesh contact's (by
// particle id and contact key) is the same bits after a forced rebuild.
TEST(dem_Rotation, RollingSpringsSurviveBroadPhases) {
  dem::Scene scene = box_scene(true);
  State st = settled_box();
  for (std::size_t i = 0; i < st.size(); ++i) st.v[i] = st.u[i] = {0.05, 0, 0.02};
  dem::Engine engine(scene);
  for (int k = 0; k < 203; ++k) engine.step(st);
  using Key = std::pair<std::int64_t, std::int64_t>;
  auto pairs = [](const State& s) {
    std::map<Key, Vec3> m;
    for (std::size_t i = 0; i + 1 < s.pair_offset.size(); ++i)
      for (std::int32_t k = s.pair_offset[i]; k < s.pair_offset[i + 1]; ++k) {
        if (!nonzero(s.pair_roll[k])) continue;
        const std::int64_t a = s.id[i], b = s.id[s.pair_j[k]];
        m[{std::min(a, b), std::max(a, b)}] = a < b ? s.pair_roll[k] : -1.0 * s.pair_roll[k];
      }
    return m;
  };
  auto slots = [](const State& s) {
    std::map<std::pair<std::int64_t, std::uint64_t>, Vec3> m;
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (s.slot_block[i] < 0) continue;
      const std::size_t base = static_cast<std::size_t>(s.slot_block[i]) * dem::kBoundarySlots;
      for (int c = 0; c < s.slot_count[i]; ++c) m[{s.id[i], s.slot_key[base + c]}] = s.slot_roll[base + c];
    }
    return m;
  };
  const auto p0 = pairs(st);
  const auto s0 = slots(st);
  ASSERT_GT(p0.size(), 100u);
  ASSERT_GT(s0.size(), 50u);
  engine.rebuild(st);
  const auto p1 = pairs(st);
  const auto s1 = slots(st);
  ASSERT_EQ(p1.size(), p0.size());
  ASSERT_EQ(s1.size(), s0.size());
  for (const auto& [k, v] : p0) {
    const auto it = p1.find(k);
    ASSERT_NE(it, p1.end());
    EXPECT_EQ(0, std::memcmp(&it->second, &v, sizeof(Vec3)));
  }
  for (const auto& [k, v] : s0) {
    const auto it = s1.find(k);
    ASSERT_NE(it, s1.end());
    EXPECT_EQ(0, std::memcmp(&it->second, &v, sizeof(Vec3)));
  }
}

// ---- Configs: the default is the translating model and adds nothing to State; bad input is
// refused by name.
const char* kBase = R"(
scene: {dt: 5.0e-6, threads: 1, gravity: [0, 0, -9.81]}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact:
  particle_particle: {normal_stiffness: 4.0e7, restitution: 0.3, friction: 0.5}
walls: [{name: floor, type: plane, point: [0, 0, 0], normal: [0, 0, 1]}]
particles:
  list:
    - {species: grain, position: [0, 0, 0.0049], velocity: [0.1, 0, 0]}
    - {species: grain, position: [0.0099, 0, 0.0049]}
    - {species: grain, position: [0.005, 0, 0.013]}
)";

dem::RunConfig load(const std::vector<std::string>& sets) {
  YAML::Node root = YAML::Load(kBase);
  for (const auto& s : sets) cosim::config::apply_override(root, s);
  return dem::load_config(root, std::filesystem::temp_directory_path().string());
}

std::string error_of(const std::vector<std::string>& sets) {
  try {
    dem::RunConfig rc = load(sets);
    std::ostringstream warn;
    dem::check_dt(rc.scene, warn);
    return "";
  } catch (const std::exception& e) {
    return e.what();
  }
}

State run(const dem::RunConfig& rc, int steps) {
  State st = rc.state;
  dem::Engine e(rc.scene);
  for (int k = 0; k < steps; ++k) e.step(st);
  return st;
}

TEST(dem_Rotation, DefaultIsTheTranslatingModelAndAddsNoState) {
  const dem::RunConfig def = load({}), tra = load({"particles.model=translating"});
  EXPECT_FALSE(def.scene.rotation.rotating());
  const State a = run(def, 2000), b = run(tra, 2000);
  EXPECT_EQ(dem::differing_arrays(a, b), "");
  EXPECT_TRUE(a.w.empty() && a.wu.empty() && a.pair_roll.empty() && a.slot_roll.empty());
  // The rotating model moves the same grains differently (the lower pair rolls).
  const State c = run(load({"particles.model=rotating"}), 2000);
  EXPECT_NE(dem::differing_arrays(a, c), "");
  EXPECT_EQ(c.w.size(), c.size());
}

TEST(dem_Rotation, BadInputIsRefusedByName) {
  auto refused = [](const std::vector<std::string>& sets, const std::string& part) {
    const std::string msg = error_of(sets);
    EXPECT_NE(msg.find(part), std::string::npos) << "message: '" << msg << "' lacks '" << part << "'";
  };
  EXPECT_EQ(error_of({"particles.model=rotating", "particles.rolling_resistance.friction=0.1"}), "");
  refused({"particles.model=spinning"}, "particles.model");
  refused({"particles.model=rotating", "particles.rolling_resistance.friction=-0.1"},
          "particles.rolling_resistance.friction");
  refused({"particles.model=rotating", "particles.rolling_resistance.friction=0"},
          "particles.rolling_resistance.friction");
  refused({"particles.model=rotating", "particles.rolling_resistance.friction=.nan"},
          "particles.rolling_resistance.friction");
  refused({"particles.model=rotating", "particles.rolling_resistance.friction=0.1",
           "particles.rolling_resistance.damping=1.5"},
          "particles.rolling_resistance.damping");
  refused({"particles.model=rotating", "particles.rolling_resistance.friction=0.1",
           "particles.rolling_resistance.stiffness_factor=-1"},
          "particles.rolling_resistance.stiffness_factor");
  refused({"particles.model=rotating", "particles.rolling_resistance.model=cdt"},
          "particles.rolling_resistance.model");
  refused({"particles.model=rotating", "particles.rolling_resistance.mu=0.1"},
          "particles.rolling_resistance");
  refused({"particles.rolling_resistance.friction=0.1"}, "needs particles.model: rotating");
  // Sleeping is supported (tests dem_SleepRotating.*): accepted from a config and in code.
  EXPECT_EQ(error_of({"particles.model=rotating", "scene.sleep.enabled=true",
                      "scene.sleep.steps=2000"}),
            "");
  dem::Scene sc = rotating_scene(0.5, 0.1);
  sc.sleep.enabled = true;
  EXPECT_NO_THROW(dem::Engine{sc});
  // A scene built in code is held to the same rules by the engine.
  sc = rotating_scene(0.5, 0.1);
  sc.rotation.rolling.friction = -1;
  EXPECT_THROW(dem::Engine{sc}, std::invalid_argument);
  // The dt check counts the spins: the tangential oscillation of a rotating contact is faster.
  dem::Scene t = rotating_scene(0.5, 0), r = t;
  t.rotation.model = dem::ParticleModel::translating;
  t.particle_particle.tangential_stiffness_ratio = r.particle_particle.tangential_stiffness_ratio = 1.0;
  EXPECT_LT(dem::largest_safe_dt(r), dem::largest_safe_dt(t));
}

}  // namespace
