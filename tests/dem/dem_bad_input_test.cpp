// Bad input is refused with a message that names the key or file and the fix.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "cosim/yaml_config.hpp"
#include "dem/checkpoint.hpp"
#include "dem/config.hpp"
#include "dem/stability.hpp"
#include "dem_test_util.hpp"

namespace {

namespace fs = std::filesystem;

const char* kBase = R"(
scene: {dt: 1.0e-5, threads: 1}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact:
  particle_particle: {normal_stiffness: 4.0e7, restitution: 0.3, friction: 0.5}
particles:
  list:
    - {species: grain, position: [0, 0, 0.1]}
    - {species: grain, position: [0.02, 0, 0.1]}
)";

std::string dir() {
  const fs::path d = fs::temp_directory_path() / "dem_bad_input";
  fs::create_directories(d);
  return d.string();
}

// Loads kBase with the overrides and returns the error message ("" if accepted).
std::string error_of(const std::vector<std::string>& sets, bool check = true) {
  try {
    YAML::Node root = YAML::Load(kBase);
    for (const auto& s : sets) cosim::config::apply_override(root, s);
    dem::RunConfig rc = dem::load_config(root, dir());
    if (check) {
      std::ostringstream warn;
      dem::check_dt(rc.scene, warn);
      dem::validate_state(rc.scene, rc.state, !rc.continues);
    }
    return "";
  } catch (const std::exception& e) {
    return e.what();
  }
}

void expect_has(const std::string& msg, const std::string& part) {
  EXPECT_NE(msg.find(part), std::string::npos) << "message: '" << msg << "' lacks '" << part << "'";
}

TEST(dem_BadInput, BaseConfigIsAccepted) { EXPECT_EQ(error_of({}), ""); }

TEST(dem_BadInput, UnknownKeysNamed) {
  const auto msg = error_of({"scene.time_step=1e-5"});
  expect_has(msg, "scene");
  expect_has(msg, "time_step");
  expect_has(msg, "broad_phase_interval");  // lists what is allowed
  expect_has(error_of({"contact.particle_particle.stifness=3"}), "stifness");
}

TEST(dem_BadInput, ATypoGetsTheKeyItMeans) {
  expect_has(error_of({"contact.particle_particle.frction=0.3"}), "did you mean 'friction'?");
  expect_has(error_of({"scene.thread=2"}), "did you mean 'threads'?");
  const auto msg = error_of({"scene.time_step=1e-5"});
  EXPECT_EQ(msg.find("did you mean"), std::string::npos) << msg;  // no allowed key is close
}

TEST(dem_BadInput, ContactLawRangesNameTheValueAndTheFix) {
  const auto msg = error_of({"contact.particle_particle.friction=-0.1"});
  expect_has(msg, "contact.particle_particle.friction: -0.1 is not allowed");
  expect_has(msg, ">= 0");
  expect_has(error_of({"contact.particle_particle.normal_stiffness=0"}),
             "contact.particle_particle.normal_stiffness: 0 is not allowed");
  expect_has(error_of({"contact.particle_wall={normal_stiffness: 4.0e7, normal_damping: -1}"}),
             "contact.particle_wall.normal_damping: -1 is not allowed");
}

TEST(dem_BadInput, ZeroOrNegativeRadius) {
  expect_has(error_of({"species[0]=x"}), "");  // malformed override must not crash
  expect_has(error_of({"particles.list=[{species: grain, position: [0,0,0], radius: 0}]"}),
             "particles.list[0].radius");
  expect_has(error_of({"particles.list=[{species: grain, position: [0,0,0], radius: -0.01}]"}),
             "positive");
  YAML::Node root = YAML::Load(kBase);
  root["species"][0]["radius"] = -0.004;
  try {
    dem::load_config(root, dir());
    FAIL();
  } catch (const std::exception& e) {
    expect_has(e.what(), "species[0].radius");
  }
}

TEST(dem_BadInput, DtAboveSafeLimitNamesTheSafeDt) {
  const auto msg = error_of({"scene.dt=1e-4"});
  expect_has(msg, "scene.dt = 0.0001");
  expect_has(msg, "Use scene.dt <=");
  // warn instead of refuse, by config
  EXPECT_EQ(error_of({"scene.dt=1e-4", "scene.stability={on_violation: warn}"}), "");
  // the limit is right: just below passes, just above fails
  YAML::Node root = YAML::Load(kBase);
  dem::RunConfig rc = dem::load_config(root, dir());
  const double safe = dem::largest_safe_dt(rc.scene);
  const double m = 2600 * 4.0 / 3 * M_PI * 0.005 * 0.005 * 0.005;
  const double k = 4e7 * 0.005 / 2;  // two equal spheres: effective length r/2
  const double tc_undamped = M_PI * std::sqrt(m / 2 / k);
  EXPECT_NEAR(safe, tc_undamped / 20, 1e-12 * safe);
  auto dt_set = [](double dt) {
    std::ostringstream s;
    s.precision(17);
    s << "scene.dt=" << dt;
    return s.str();
  };
  EXPECT_EQ(error_of({dt_set(safe * 0.999)}), "");
  EXPECT_NE(error_of({dt_set(safe * 1.001)}), "");
}

// A checkpoint's overlaps are refused when it starts a new scene and accepted when it continues
// its own run (particles.keep_time), where they are the run's, not a set-up error.
TEST(dem_BadInput, CheckpointOverlapsRefusedUnlessTheRunContinues) {
  dem::State s;
  dem::add_particle(s, {0, 0, 0.1}, {}, 0.005, 1e-3, 0, 0);
  dem::add_particle(s, {0.006, 0, 0.1}, {}, 0.005, 1e-3, 0, 1);  // 40 % of r
  s.step = 123;
  const std::string path = (fs::path(dir()) / "overlapping.h5").string();
  dem::save_checkpoint(s, path);
  const std::string ck = "particles={checkpoint: " + path;
  const auto fresh = error_of({ck + "}"});
  expect_has(fresh, "overlap_tolerance");
  EXPECT_EQ(error_of({ck + ", keep_time: true}"}), "");
  // Particles added to a continued checkpoint are a new set-up again: checked.
  expect_has(error_of({ck + ", keep_time: true, list: [{species: grain, position: [1, 1, 1]}]}"}),
             "overlap_tolerance");
}

TEST(dem_BadInput, OverlappingInitialParticles) {
  const auto msg = error_of(
      {"particles.list=[{species: grain, position: [0,0,0]}, {species: grain, position: [0.009,0,0]}]"});
  expect_has(msg, "overlap");
  expect_has(msg, "overlap_tolerance");
  // within the tolerance (1 % of r = 5e-5 m) is accepted
  EXPECT_EQ(error_of({"particles.list=[{species: grain, position: [0,0,0]}, {species: grain, "
                      "position: [0.00997,0,0]}]"}),
            "");
}

TEST(dem_BadInput, MissingAndCorruptMesh) {
  auto msg = error_of({"tools=[{name: blade, mesh: no_such_blade.stl}]"});
  expect_has(msg, "tools[0].mesh");
  expect_has(msg, "no_such_blade.stl");
  expect_has(msg, "not found");
  const fs::path bad = fs::path(dir()) / "corrupt.stl";
  {
    std::ofstream f(bad);
    f << "solid broken\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 zz\n";
  }
  msg = error_of({"tools=[{name: blade, mesh: corrupt.stl}]"});
  expect_has(msg, "corrupt.stl");
  expect_has(msg, "re-export");
  const fs::path empty = fs::path(dir()) / "empty.obj";
  {
    std::ofstream f(empty);
    f << "# nothing\nv 0 0 0\n";
  }
  msg = error_of({"tools=[{name: blade, mesh: empty.obj}]"});
  expect_has(msg, "empty.obj");
}

TEST(dem_BadInput, BadValuesNameTheKey) {
  expect_has(error_of({"scene.broad_phase_interval=0"}), "scene.broad_phase_interval");
  expect_has(error_of({"scene.guard=sometimes"}), "scene.guard");
  expect_has(error_of({"contact.particle_particle.restitution=1.5"}),
             "contact.particle_particle.restitution");
  expect_has(error_of({"contact.particle_particle.normal_damping=3"}), "exactly one of");
  expect_has(error_of({"particles.list[0].species=gravel"}), "");
  expect_has(error_of({"particles.list=[{species: gravel, position: [0,0,0]}]"}), "gravel");
}

}  // namespace
