// The soil keys of the DEM config (docs/dem.md, docs/soil.md): contact laws per wall and per tool
// (walls[].contact, tools[].contact), a bed that reloads whatever its overlaps (its recorded
// /bed/max_overlap_ratio), particles.insert and prepare:, and dem_run accepting (and ignoring) a
// dem_service config's service: section.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "cosim/yaml_config.hpp"
#include "dem/checkpoint.hpp"
#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem/packing.hpp"
#include "dem/service.hpp"
#include "dem/stability.hpp"

namespace {

namespace fs = std::filesystem;
using dem::Vec3;

// One grain of r 5 mm resting on a floor, sliding along x at 0.1 m/s.
const char* kSlide = R"(
scene: {dt: 2.0e-5, gravity: [0, 0, -9.81]}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact:
  particle_particle: {normal_stiffness: 2.0e4, stiffness_unit: N/m, restitution: 0.3, friction: 0.5}
walls:
  - {name: floor, type: plane, point: [0, 0, 0], normal: [0, 0, 1]}
  - {name: bin, type: box, min: [-1, -1, -1], max: [1, 1, 1]}
particles:
  list: [{species: grain, position: [0, 0, 0.004999], velocity: [0.1, 0, 0]}]
)";

dem::RunConfig load(const YAML::Node& root) { return dem::load_config(root, "."); }

// x velocity after 0.05 s.
double slide(const dem::RunConfig& rc) {
  dem::State s = rc.state;
  dem::Engine engine(rc.scene);
  for (int k = 0; k < 2500; ++k) engine.step(s);
  return s.v[0].x;
}

TEST(dem_SoilConfig, AWallWithItsOwnFrictionLetsAGrainSlide) {
  YAML::Node root = YAML::Load(kSlide);
  const dem::RunConfig rough = load(root);
  ASSERT_EQ(rough.scene.walls.size(), 6u);  // the plane and the box's 5 faces
  for (const dem::Wall& w : rough.scene.walls) EXPECT_EQ(w.law, -1);
  EXPECT_TRUE(rough.scene.boundary_laws.empty());
  // mu g = 4.9 m/s^2 stops 0.1 m/s within 0.02 s.
  EXPECT_NEAR(slide(rough), 0.0, 1e-3);

  root["walls"][0]["contact"] = YAML::Load("{friction: 0.0}");
  root["walls"][1]["contact"] = YAML::Load("{friction: 0.9, restitution: 0.5}");
  const dem::RunConfig smooth = load(root);
  ASSERT_EQ(smooth.scene.boundary_laws.size(), 2u);
  EXPECT_EQ(smooth.scene.walls[0].law, 0);
  for (std::size_t k = 1; k < 6; ++k) EXPECT_EQ(smooth.scene.walls[k].law, 1) << k;
  EXPECT_EQ(smooth.scene.wall_law(0).friction, 0.0);
  EXPECT_EQ(smooth.scene.wall_law(3).friction, 0.9);
  EXPECT_EQ(smooth.scene.wall_law(3).restitution, 0.5);
  // The rest is particle_wall's (here particle_particle's: no particle_wall given).
  EXPECT_EQ(smooth.scene.wall_law(0).normal_stiffness, 2.0e4);
  EXPECT_FALSE(smooth.scene.wall_law(0).stiffness_per_length);
  EXPECT_EQ(smooth.scene.particle_wall.friction, 0.5);
  EXPECT_NEAR(slide(smooth), 0.1, 1e-6);  // frictionless floor: no loss
}

TEST(dem_SoilConfig, AToolWithItsOwnLawAndTheDefaultLawIsTheSameBits) {
  // A grain pushed by the blade mesh: with tools[0].contact {} (particle_wall's own values)
  // every bit equals the run without it; with friction 0 the result differs.
  const std::string cfg = std::string(R"(
scene: {dt: 2.0e-5, gravity: [0, 0, -9.81]}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.01}]
contact:
  particle_particle: {normal_stiffness: 2.0e4, stiffness_unit: N/m, restitution: 0.3, friction: 0.5}
  particle_wall: {normal_stiffness: 3.0e4, stiffness_unit: N/m, restitution: 0.4, friction: 0.6}
walls: [{name: floor, type: plane, point: [0, 0, -0.2], normal: [0, 0, 1]}]
tools:
  - name: blade
    mesh: )") + DEM_SOURCE_DIR + R"(/configs/dem/meshes/blade.obj
particles:
  list:
    - {species: grain, position: [0.02, -0.05, 0.00999], velocity: [0.1, 0, 0]}
    - {species: grain, position: [0.02, 0.0, 0.00999], velocity: [0.1, 0.02, 0]}
    - {species: grain, position: [0.02, 0.05, 0.00999], velocity: [0.12, 0, 0]}
    - {species: grain, position: [0.06, 0.0, 0.05], velocity: [0.0, 0, 0]}
)";
  YAML::Node root = YAML::Load(cfg);
  auto run = [](const dem::RunConfig& rc) {
    dem::State s = rc.state;
    dem::Engine engine(rc.scene);
    for (int k = 0; k < 4000; ++k) engine.step(s);
    return s;
  };
  const dem::State base = run(load(root));
  root["tools"][0]["contact"] = YAML::Load("{}");
  const dem::RunConfig same_cfg = load(root);
  ASSERT_EQ(same_cfg.scene.tools[0].law, 0);
  const dem::State same = run(same_cfg);
  ASSERT_EQ(base.size(), same.size());
  double touched = 0;
  for (std::size_t i = 0; i < base.size(); ++i) {
    EXPECT_EQ(base.x[i].x, same.x[i].x);
    EXPECT_EQ(base.x[i].y, same.x[i].y);
    EXPECT_EQ(base.x[i].z, same.x[i].z);
    EXPECT_EQ(base.v[i].z, same.v[i].z);
    touched += std::abs(base.v[i].x) + std::abs(base.v[i].y);
  }
  root["tools"][0]["contact"] = YAML::Load("{friction: 0.0}");
  const dem::State other = run(load(root));
  double diff = 0;
  for (std::size_t i = 0; i < base.size(); ++i) diff += norm(base.x[i] - other.x[i]);
  EXPECT_GT(diff, 1e-9) << "the blade's own law was not used (grains moved " << touched << ")";
}

TEST(dem_SoilConfig, BadWallAndToolLawsAreRefusedByName) {
  auto message = [](const std::string& key, const std::string& value) {
    YAML::Node root = YAML::Load(kSlide);
    root["walls"][1]["contact"] = YAML::Load(value);
    (void)key;
    try {
      dem::load_config(root, ".");
    } catch (const cosim::config::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message("", "{friction: -1}").find("walls[1].contact.friction"), std::string::npos);
  EXPECT_NE(message("", "{frction: 0.2}").find("walls[1].contact"), std::string::npos);
  EXPECT_NE(message("", "0.3").find("walls[1].contact: expected a map"), std::string::npos);
  EXPECT_NE(message("", "{restitution: 2}").find("walls[1].contact.restitution"), std::string::npos);
  // A stiffer wall law counts in the dt check.
  YAML::Node root = YAML::Load(kSlide);
  root["walls"][0]["contact"] = YAML::Load("{normal_stiffness: 2.0e7}");
  const dem::RunConfig rc = load(root);
  std::ostringstream warn;
  try {
    dem::check_dt(rc.scene, warn);
    FAIL() << "a wall 1000x stiffer than the grains needs a smaller dt";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("wall or tool law 0"), std::string::npos) << e.what();
  }
}

TEST(dem_SoilConfig, ABedReloadsWithTheOverlapItWasMadeWith) {
  const fs::path dir = fs::temp_directory_path() / "dem_soil_config_reload";
  fs::create_directories(dir);
  // Two grains overlapping by 3 % of a radius: more than the 1 % default tolerance.
  dem::State s;
  for (int k = 0; k < 2; ++k)
    dem::add_particle(s, {0.0097 * k, 0, 0.02}, {}, 0.005, 2600 * 4.0 / 3 * M_PI * 1.25e-7, 0, k);
  const std::string bed = (dir / "bed.h5").string();
  dem::save_checkpoint(s, bed);
  YAML::Node root = YAML::Load(kSlide);
  root["particles"] = YAML::Load("{checkpoint: " + bed + "}");
  {
    const dem::RunConfig rc = load(root);
    EXPECT_EQ(rc.scene.stability.overlap_tolerance, 0.01);
    EXPECT_THROW(dem::validate_state(rc.scene, rc.state, !rc.continues), std::invalid_argument);
  }
  dem::write_bed_record(bed, 0.06, std::nullopt);  // the bed's own record: 0.3 mm / 5 mm
  {
    const dem::RunConfig rc = load(root);
    EXPECT_NEAR(rc.scene.stability.overlap_tolerance, 0.06, 1e-9);
    EXPECT_NO_THROW(dem::validate_state(rc.scene, rc.state, !rc.continues));
  }
  fs::remove_all(dir);
}

std::string run_dem(const fs::path& config, const std::string& extra, int* status) {
  const std::string log = config.string() + ".log";
  const std::string cmd = std::string(DEM_RUN_EXE) + " " + config.string() + " " + extra + " > " +
                          log + " 2>&1";
  *status = std::system(cmd.c_str());
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(dem_SoilConfig, DemRunRecordsItsSettledBedAndReloadsIt) {
  const fs::path dir = fs::temp_directory_path() / "dem_soil_config_settle";
  fs::remove_all(dir);
  fs::create_directories(dir);
  // A soft dense column settles with overlaps far beyond 1 %; the service: section of a
  // dem_service config is accepted and named as ignored.
  std::ofstream(dir / "settle.yaml") << R"(
scene: {dt: 2.0e-5, gravity: [0, 0, -9.81]}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact:
  particle_particle: {normal_stiffness: 200, stiffness_unit: N/m, restitution: 0.3, friction: 0.5}
walls: [{name: bin, type: box, min: [0, 0, 0], max: [0.012, 0.012, 0.5]}]
particles:
  fill: [{species: grain, min: [0, 0, 0], max: [0.012, 0.012, 0.4], count: 15, seed: 1}]
settle: {ke_per_particle: 1.0e-9, max_time: 2.0, checkpoint: )" << (dir / "bed.h5").string() << R"(}
run: {duration: 0}
output: {file: )" << (dir / "out.h5").string() << R"(}
service: {report_every: 30}
)";
  int status = 0;
  const std::string log = run_dem(dir / "settle.yaml", "", &status);
  ASSERT_EQ(status, 0) << log;
  EXPECT_NE(log.find("service: section is ignored"), std::string::npos) << log;
  const std::optional<double> made = dem::read_bed_overlap((dir / "bed.h5").string());
  ASSERT_TRUE(made.has_value());
  EXPECT_GT(*made, 0.01) << "the column was meant to settle beyond the default tolerance";
  std::ofstream(dir / "reload.yaml") << R"(
scene: {dt: 2.0e-5, gravity: [0, 0, -9.81]}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact:
  particle_particle: {normal_stiffness: 200, stiffness_unit: N/m, restitution: 0.3, friction: 0.5}
walls: [{name: bin, type: box, min: [0, 0, 0], max: [0.012, 0.012, 0.5]}]
particles: {checkpoint: )" << (dir / "bed.h5").string() << R"(}
run: {duration: 0.001}
output: {file: )" << (dir / "out2.h5").string() << R"(}
)";
  const std::string log2 = run_dem(dir / "reload.yaml", "", &status);
  EXPECT_EQ(status, 0) << log2;
  fs::remove_all(dir);
}

TEST(dem_SoilConfig, InsertAndPrepareAreReadAndBadValuesRefused) {
  const std::string base = R"(
scene: {dt: 2.5e-5, gravity: [0, 0, -9.81]}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact:
  particle_particle: {normal_stiffness: 2.0e4, stiffness_unit: N/m, restitution: 0.3, friction: 0.5}
walls: [{name: bin, type: box, min: [0, 0, 0], max: [0.1, 0.1, 0.5]}]
particles:
  insert: [{species: grain, min: [0, 0, 0], max: [0.1, 0.1, 0.2], count: 300, seed: 4}]
prepare: {deposition_friction: 0.2, margin: 2.0, ke_per_particle: 1.0e-7, max_time: 1.0}
)";
  const dem::RunConfig rc = load(YAML::Load(base));
  EXPECT_EQ(rc.state.size(), 300u);
  EXPECT_EQ(dem::max_overlap_ratio(rc.scene, rc.state), 0.0);
  EXPECT_TRUE(rc.prepare.enabled);
  EXPECT_EQ(rc.prepare.deposition_friction, 0.2);
  EXPECT_EQ(rc.prepare.margin, 2.0);
  EXPECT_EQ(rc.prepare.ke_per_particle, 1e-7);
  auto refused = [&](const std::string& key, const std::string& value) {
    YAML::Node root = YAML::Load(base);
    cosim::config::apply_override(root, key + "=" + value);
    try {
      dem::load_config(root, ".");
    } catch (const cosim::config::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(refused("prepare.deposition_friction", "-0.1").find("prepare.deposition_friction"), std::string::npos);
  EXPECT_NE(refused("prepare.margin", "-1").find("prepare.margin"), std::string::npos);
  EXPECT_NE(refused("prepare.max_time", "0").find("prepare.max_time"), std::string::npos);
  EXPECT_NE(refused("prepare.deposit", "1").find("prepare"), std::string::npos);
  EXPECT_NE(refused("particles.insert.0.count", "-5").find("particles.insert[0].count"), std::string::npos);
  EXPECT_NE(refused("particles.insert.0.species", "gravel").find("particles.insert[0].species"), std::string::npos);
  EXPECT_NE(refused("particles.insert.0.count", "5000").find("raise max.z"), std::string::npos);
  EXPECT_NE(refused("particles.insert.0.max", "[0.1, 0.1, 0.005]").find("particles.insert[0]"), std::string::npos);
  EXPECT_NE(refused("particles.insert.0.seed", "-1").find("particles.insert[0].seed"), std::string::npos);
  EXPECT_NE(refused("particles.insert", "{species: grain}").find("particles.insert: expected a list"), std::string::npos);
}

TEST(dem_SoilConfig, DemServiceRefusesToPrepareABed) {
  YAML::Node root = YAML::Load(kSlide);
  root["prepare"] = YAML::Load("{deposition_friction: 0.1}");
  try {
    dem::read_service_options(root);
    FAIL() << "dem_service cannot run a deposition inside a co-simulation step";
  } catch (const cosim::config::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("prepare: dem_service does not prepare beds"), std::string::npos)
        << e.what();
  }
}

}  // namespace
