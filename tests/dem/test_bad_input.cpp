// Bad input is refused with a message that names the key or file and the fix.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "cosim/yaml_config.hpp"
#include "dem/checkpoint.hpp"
#include "dem/config.hpp"
#include "dem/output.hpp"
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

// --- Meshes: a truncated or damaged STL and a vertex that is not a finite point are named. ----

const char* kSquare =
    "solid square\n"
    " facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 0.1 0 0\n   vertex 0 0.1 0\n"
    "  endloop\n endfacet\n"
    " facet normal 0 0 1\n  outer loop\n   vertex 0.1 0 0\n   vertex 0.1 0.1 0\n   vertex 0 0.1 0\n"
    "  endloop\n endfacet\n"
    "endsolid square\n";

// The error for a tool whose mesh file holds `text` ("" if accepted).
std::string mesh_error(const std::string& file, const std::string& text) {
  {
    std::ofstream f(fs::path(dir()) / file, std::ios::binary);
    f << text;
  }
  return error_of({"tools=[{name: blade, mesh: " + file + "}]"});
}

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  s.replace(s.find(from), from.size(), to);
  return s;
}

std::string binary_stl(const std::vector<float>& xyz, std::size_t drop_bytes = 0) {
  std::string b(80, ' ');
  const std::uint32_t n = static_cast<std::uint32_t>(xyz.size() / 9);
  b.append(reinterpret_cast<const char*>(&n), 4);
  for (std::uint32_t t = 0; t < n; ++t) {
    const float normal[3] = {0, 0, 1};
    b.append(reinterpret_cast<const char*>(normal), 12);
    b.append(reinterpret_cast<const char*>(&xyz[9 * t]), 36);
    b.append(2, '\0');
  }
  return b.substr(0, b.size() - drop_bytes);
}

TEST(dem_BadInput, WellFormedStlIsAccepted) {
  EXPECT_EQ(mesh_error("square.stl", kSquare), "");
  EXPECT_EQ(mesh_error("square_bin.stl", binary_stl({0, 0, 0, 0.1f, 0, 0, 0, 0.1f, 0})), "");
}

TEST(dem_BadInput, TruncatedAsciiStlIsRefused) {
  const std::string s = kSquare;
  const auto msg = mesh_error("truncated.stl", s.substr(0, s.rfind("endloop")));
  expect_has(msg, "tools[0].mesh: mesh file '");
  expect_has(msg, "truncated.stl': the ASCII STL ends at line 14 inside solid 'at line 1' after 1 complete "
                  "triangles, where 'endloop' should follow: the file is truncated; re-export it");
  expect_has(mesh_error("no_endsolid.stl", s.substr(0, s.find("endsolid"))), "where 'endsolid' should follow");
  expect_has(mesh_error("junk.stl", replaced(s, "endloop", "endlop")), "line 7: expected 'endloop', got 'endlop'");
}

TEST(dem_BadInput, TruncatedBinaryStlIsRefused) {
  const auto msg = mesh_error("cut.stl", binary_stl({0, 0, 0, 0.1f, 0, 0, 0, 0.1f, 0}, 10));
  expect_has(msg, "a binary STL of 124 bytes, but its header says 1 triangles, which take 84 + 50 x 1 = 134 bytes");
  expect_has(msg, "re-export");
}

TEST(dem_BadInput, NonFiniteOrHugeVertexIsNamedNotCalledZeroArea) {
  const std::string s = kSquare;
  for (const char* bad : {"nan", "-nan", "inf", "-inf"}) {
    const auto msg = mesh_error("bad_vertex.stl", replaced(s, "vertex 0.1 0.1 0", std::string("vertex 0.1 ") + bad + " 0"));
    expect_has(msg, std::string("line 12: vertex 4 (triangle 1, corner 1) y is '") + bad + "': not a finite number");
    EXPECT_EQ(msg.find("zero area"), std::string::npos) << msg;
  }
  auto msg = mesh_error("huge_vertex.stl", replaced(s, "vertex 0 0.1 0", "vertex 0 0.1 1e300"));
  expect_has(msg, "vertex 2 (triangle 0, corner 2) z is 1e300, beyond the 32-bit floats an STL stores");
  // In binary: a float that is not finite, named with its value.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  msg = mesh_error("nan_bin.stl", binary_stl({0, 0, 0, 0.1f, 0, 0, 0, 0.1f, nan}));
  expect_has(msg, "vertex 2 (triangle 0, corner 2) is (0, 0.100000001, nan): not a finite number");
  // Finite but absurd after scaling: named too.
  msg = mesh_error("far.stl", replaced(s, "vertex 0 0.1 0", "vertex 0 0.1 3e30"));
  expect_has(msg, "triangle 0 corner 2 is at (0, 0.100000001, 3.0000002e+30) in the file, more than 1e6 m");
  // OBJ (through assimp): the triangle and corner with the value.
  msg = mesh_error("nan.obj", "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n");
  if (msg.find("could not be read") == std::string::npos)  // assimp may refuse "nan" itself
    expect_has(msg, "not a finite number");
  EXPECT_EQ(msg.find("zero area"), std::string::npos) << msg;
}

// --- Particles, YAML, files. --------------------------------------------------------------------

TEST(dem_BadInput, EmptyParticleSetIsRefused) {
  expect_has(error_of({"particles.list=[]"}),
             "particles: the scene has no particles (particles.list is empty): give at least one in "
             "particles.list, a particles.fill count > 0 or a particles.checkpoint with particles");
  expect_has(error_of({"particles={fill: [{species: grain, min: [0, 0, 0], max: [0.1, 0.1, 0.1], count: 0}]}"}),
             "(particles.fill places none (count 0))");
  expect_has(error_of({"particles={}"}), "(none given)");
}

TEST(dem_BadInput, FillRegionInTheWrongUnitsIsRefused) {
  expect_has(error_of({"particles={fill: [{species: grain, min: [0, 0, 0], max: [1.0e6, 1.0e6, 1], count: 10}]}"}),
             "lattice cells (pitch 0.0115 m) across: give min and max in metres");
}

TEST(dem_BadInput, DuplicateKeyInADemConfigIsRefused) {
  try {
    cosim::config::load_string(std::string(kBase) + "scene: {dt: 1.0e-4}\n", "scene.yaml");
    FAIL() << "accepted";
  } catch (const cosim::config::ConfigError& e) {
    expect_has(e.what(), "scene.yaml:11:1: duplicate key 'scene' (first at line 2)");
  }
}

TEST(dem_BadInput, OutputOntoAnInputOrAnotherOutputIsRefused) {
  YAML::Node root = YAML::Load(kBase);
  {
    std::ofstream f(fs::path(dir()) / "plate.stl");
    f << kSquare;
  }
  cosim::config::apply_override(root, "tools=[{name: blade, mesh: plate.stl}]");
  dem::RunConfig rc = dem::load_config(root, dir());
  const std::string cfg = (fs::path(dir()) / "scene.yaml").string();
  {
    std::ofstream f(cfg);
    f << kBase;
  }
  const std::string mesh = (fs::path(dir()) / "plate.stl").string();
  auto refusal = [&](const dem::RunConfig& r) {
    try {
      dem::check_files(r, cfg, "--output");
      return std::string();
    } catch (const cosim::config::ConfigError& e) {
      return std::string(e.what());
    }
  };
  rc.output.file = (fs::path(dir()) / "out.h5").string();
  EXPECT_EQ(refusal(rc), "");
  rc.output.file = mesh;
  expect_has(refusal(rc), "--output '" + mesh + "' is the same file as tools[0].mesh '" + mesh + "'");
  rc.output.file = cfg;
  expect_has(refusal(rc), "is the same file as the config file");
  rc.output.file = (fs::path(dir()) / "out.h5").string();
  rc.output.checkpoint = (fs::path(dir()) / "out.xdmf").string();
  expect_has(refusal(rc), "the XDMF file beside --output '" + (fs::path(dir()) / "out.xdmf").string() +
                              "' and output.checkpoint");
}

// The DEM's output file replaces an existing one only at its first flush.
TEST(dem_BadInput, ExistingOutputIsReplacedOnlyWhenTheRunWrites) {
  const fs::path out = fs::path(dir()) / "replace_me.h5";
  {
    std::ofstream f(out);
    f << "old";
  }
  YAML::Node root = YAML::Load(kBase);
  dem::RunConfig rc = dem::load_config(root, dir());
  auto text = [&] {
    std::ifstream f(out);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
  };
  {
    dem::RunOutput o(out.string(), rc.scene, rc.config_text);
    EXPECT_EQ(text(), "old");
  }  // destroyed: flushes, so the file is replaced
  EXPECT_EQ(text().rfind("\x89HDF", 0), 0u);
}

}  // namespace

// performance.close_margin is a fraction of r_max like the skin, and below it.
TEST(dem_BadInput, CloseMarginOutsideZeroToSkinIsRefused) {
  expect_has(error_of({"performance.close_margin=-0.1"}),
             "performance.close_margin: must be >= 0 and below scene.skin");
  expect_has(error_of({"performance.close_margin=0.5", "scene.skin=0.5"}),
             "performance.close_margin: must be >= 0 and below scene.skin (now 0.5");
  expect_has(error_of({"performance.close_margin=0.5", "scene.skin=0.5"}),
             "0 turns close pairs off");
}

TEST(dem_BadInput, UnknownPairScheduleIsRefused) {
  expect_has(error_of({"performance.pair_schedule=fast"}),
             "performance.pair_schedule: 'fast' is not allowed (allowed: blocks, ranges)");
  expect_has(error_of({"performance.min_particles_per_thread=0"}),
             "performance.min_particles_per_thread: must be >= 1");
  expect_has(error_of({"performance.threads=2"}), "performance.threads");
}

// The performance switches left the scene: the old keys are refused naming the new ones.
TEST(dem_BadInput, PerformanceKeysInTheSceneAreRefusedNamingTheirNewPlace) {
  expect_has(error_of({"scene.close_margin=0.1"}),
             "scene.close_margin: moved to performance.close_margin");
  expect_has(error_of({"scene.pair_schedule=ranges"}),
             "scene.pair_schedule: moved to performance.pair_schedule");
  expect_has(error_of({"scene.min_particles_per_thread=1"}),
             "scene.min_particles_per_thread: moved to performance.min_particles_per_thread");
  // Set in their new place they are taken.
  EXPECT_EQ(error_of({"performance.close_margin=0.1", "performance.pair_schedule=ranges",
                      "performance.min_particles_per_thread=1"}),
            "");
}
