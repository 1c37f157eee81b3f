// Material files (docs/soil.md#material-files): materials.<name>.file gives the density, the
// radius, the particle law and the deposition friction; the config's own keys win; a missing
// or malformed file is refused naming materials.<name>.file.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "cosim/yaml_config.hpp"
#include "dem/config.hpp"

namespace {

namespace fs = std::filesystem;

const char* kMaterial = R"(
name: test_sand
density: 2650
radius: {distribution: uniform, min: 0.004, max: 0.005}
contact:
  particle_particle: {normal_stiffness: 3.0e4, stiffness_unit: N/m, restitution: 0.3,
                      tangential_stiffness_ratio: 0.5, friction: 0.22}
prepare: {deposition_friction: 0.1}
calibration: {status: test}
)";

// A bin with two listed grains; the material comes from the file in `dir`.
const char* kScene = R"(
scene: {dt: 2.0e-5, gravity: [0, 0, -9.81]}
materials: {sand: {file: sand.yaml}}
species: [{name: grain, material: sand}]
walls: [{name: bin, type: box, min: [-0.1, -0.1, 0], max: [0.1, 0.1, 0.2]}]
particles:
  list: [{species: grain, position: [0, 0, 0.05]}, {species: grain, position: [0.02, 0, 0.05]}]
prepare: {ke_per_particle: 1.0e-9}
)";

struct dem_MaterialFile : ::testing::Test {
  fs::path dir;
  void SetUp() override {
    dir = fs::temp_directory_path() /
          ("dem_material_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::create_directories(dir);
  }
  void TearDown() override { fs::remove_all(dir); }
  void write(const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
  }
  dem::RunConfig load(const YAML::Node& root) { return dem::load_config(root, dir.string()); }
  // The message of the ConfigError that loading `root` raises ("" when none).
  std::string refusal(const YAML::Node& root) {
    try {
      load(root);
    } catch (const cosim::config::ConfigError& e) {
      return e.what();
    }
    return "";
  }
};

TEST_F(dem_MaterialFile, GivesDensityRadiusLawAndDepositionFriction) {
  write("sand.yaml", kMaterial);
  const dem::RunConfig rc = load(YAML::Load(kScene));
  ASSERT_EQ(rc.scene.species.size(), 1u);
  EXPECT_DOUBLE_EQ(rc.scene.species[0].density, 2650.0);
  EXPECT_DOUBLE_EQ(rc.scene.species[0].radius.min, 0.004);
  EXPECT_DOUBLE_EQ(rc.scene.species[0].radius.max, 0.005);
  EXPECT_DOUBLE_EQ(rc.scene.particle_particle.friction, 0.22);
  EXPECT_DOUBLE_EQ(rc.scene.particle_particle.tangential_stiffness_ratio, 0.5);
  EXPECT_DOUBLE_EQ(rc.scene.particle_wall.friction, 0.22);  // no particle_wall: the particle law
  EXPECT_DOUBLE_EQ(rc.prepare.deposition_friction, 0.1);
  bool named = false;
  for (const auto& f : rc.inputs) named |= f.what == "materials.sand.file";
  EXPECT_TRUE(named) << "the material file is an input (no output may overwrite it)";
  // The stored config text is the resolved one: a run records the law it ran with.
  EXPECT_NE(rc.config_text.find("0.22"), std::string::npos);
}

TEST_F(dem_MaterialFile, TheConfigsOwnKeysWin) {
  write("sand.yaml", kMaterial);
  YAML::Node root = YAML::Load(kScene);
  root["contact"]["particle_particle"]["friction"] = 0.4;
  root["contact"]["particle_wall"] = YAML::Load("{normal_stiffness: 3.0e4, stiffness_unit: N/m, "
                                                "restitution: 0.3, friction: 0.0}");
  root["species"][0]["radius"] = 0.006;
  root["prepare"]["deposition_friction"] = 0.0;
  const dem::RunConfig rc = load(root);
  EXPECT_DOUBLE_EQ(rc.scene.particle_particle.friction, 0.4);
  EXPECT_DOUBLE_EQ(rc.scene.particle_particle.tangential_stiffness_ratio, 0.5);  // the rest from the file
  EXPECT_DOUBLE_EQ(rc.scene.particle_wall.friction, 0.0);
  EXPECT_DOUBLE_EQ(rc.scene.species[0].radius.min, 0.006);
  EXPECT_DOUBLE_EQ(rc.scene.species[0].density, 2650.0);
  EXPECT_DOUBLE_EQ(rc.prepare.deposition_friction, 0.0);
}

TEST_F(dem_MaterialFile, GivesTheParticleModelItWasCalibratedFor) {
  // A material of the rotating model (configs/materials/dry_sand_rotating.yaml) names it; the
  // scene runs it unless the config says otherwise; a bad entry is refused by name.
  const std::string rotating = std::string(kMaterial) +
      "particles: {model: rotating, rolling_resistance: {friction: 0.3, damping: 0.3}}\n";
  write("sand.yaml", rotating);
  dem::RunConfig rc = load(YAML::Load(kScene));
  EXPECT_TRUE(rc.scene.rotation.rotating());
  EXPECT_EQ(rc.scene.rotation.rolling.kind, dem::RollingResistance::Kind::epsd);
  EXPECT_DOUBLE_EQ(rc.scene.rotation.rolling.friction, 0.3);
  EXPECT_EQ(rc.state.size(), 2u);  // the config's own particles section kept
  YAML::Node root = YAML::Load(kScene);
  root["particles"]["rolling_resistance"] = YAML::Load("{friction: 0.1, damping: 0.3}");
  rc = load(root);
  EXPECT_TRUE(rc.scene.rotation.rotating());
  EXPECT_DOUBLE_EQ(rc.scene.rotation.rolling.friction, 0.1);  // the config's own key wins
  root = YAML::Load(kScene);
  root["particles"]["model"] = "translating";  // another model: the material's rolling resistance stays out
  rc = load(root);
  EXPECT_FALSE(rc.scene.rotation.rotating());
  write("sand.yaml", kMaterial);
  EXPECT_FALSE(load(YAML::Load(kScene)).scene.rotation.rotating());  // none named: translating
  write("sand.yaml", std::string(kMaterial) + "particles: rotating\n");
  std::string m = refusal(YAML::Load(kScene));
  EXPECT_NE(m.find("materials.sand.file"), std::string::npos) << m;
  EXPECT_NE(m.find(".particles: expected a map"), std::string::npos) << m;
  write("sand.yaml", std::string(kMaterial) + "particles: {model: rotating, count: 3}\n");
  m = refusal(YAML::Load(kScene));
  EXPECT_NE(m.find("unknown key 'count'"), std::string::npos) << m;
  write("sand.yaml", std::string(kMaterial) + "particles: {model: spinning}\n");
  m = refusal(YAML::Load(kScene));
  EXPECT_NE(m.find("particles.model"), std::string::npos) << m;
}

TEST_F(dem_MaterialFile, AMissingOrMalformedFileIsRefusedByName) {
  const YAML::Node root = YAML::Load(kScene);
  std::string m = refusal(root);
  EXPECT_NE(m.find("materials.sand.file"), std::string::npos) << m;
  EXPECT_NE(m.find("no such file"), std::string::npos) << m;

  write("sand.yaml", "density: [2650\nradius: 0.004\n");
  m = refusal(root);
  EXPECT_NE(m.find("materials.sand.file"), std::string::npos) << m;
  EXPECT_NE(m.find("not valid YAML"), std::string::npos) << m;

  write("sand.yaml", "- 2650\n");
  m = refusal(root);
  EXPECT_NE(m.find("expected a map"), std::string::npos) << m;

  std::string text = kMaterial;
  write("sand.yaml", text + "friction: 0.3\n");
  m = refusal(root);
  EXPECT_NE(m.find("materials.sand.file"), std::string::npos) << m;
  EXPECT_NE(m.find("unknown key 'friction'"), std::string::npos) << m;

  write("sand.yaml", "density: 2650\nradius: 0.004\n");
  m = refusal(root);
  EXPECT_NE(m.find(".contact: missing"), std::string::npos) << m;

  write("sand.yaml", "density: -1\nradius: 0.004\ncontact: {particle_particle: {friction: 0.2}}\n");
  m = refusal(root);
  EXPECT_NE(m.find("density"), std::string::npos) << m;

  write("sand.yaml", "density: 2650\nradius: 0.004\ncontact: {particle_particle: {friction: 0.2}}\n"
                     "prepare: {deposition_friction: -0.1}\n");
  m = refusal(root);
  EXPECT_NE(m.find("prepare.deposition_friction: must be >= 0"), std::string::npos) << m;

  // The file's law is validated as contact.particle_particle after the merge.
  write("sand.yaml", "density: 2650\nradius: 0.004\ncontact: {particle_particle: {friction: -0.2}}\n");
  m = refusal(root);
  EXPECT_NE(m.find("contact.particle_particle"), std::string::npos) << m;

  fs::create_directories(dir / "folder.yaml");
  YAML::Node folder = YAML::Clone(root);
  folder["materials"]["sand"]["file"] = "folder.yaml";
  m = refusal(folder);
  EXPECT_NE(m.find("is a folder"), std::string::npos) << m;
}

TEST_F(dem_MaterialFile, DensityBesideAFileAndTwoLawsAreRefused) {
  write("sand.yaml", kMaterial);
  write("gravel.yaml", kMaterial);
  YAML::Node root = YAML::Load(kScene);
  root["materials"]["sand"]["density"] = 2600;
  std::string m = refusal(root);
  EXPECT_NE(m.find("materials.sand"), std::string::npos) << m;
  EXPECT_NE(m.find("unknown key 'density'"), std::string::npos) << m;

  root = YAML::Load(kScene);
  root["materials"]["gravel"]["file"] = "gravel.yaml";
  m = refusal(root);
  EXPECT_NE(m.find("name one material file"), std::string::npos) << m;

  root = YAML::Load(kScene);
  root["materials"]["sand"]["file"] = "";
  m = refusal(root);
  EXPECT_NE(m.find("materials.sand.file: empty"), std::string::npos) << m;
}

// The shipped material loads in a scene, and the random bed config runs with it named.
TEST(dem_MaterialFileShipped, DrySandLoads) {
  YAML::Node root = YAML::Load(kScene);
  root["materials"]["sand"]["file"] = "configs/materials/dry_sand.yaml";
  const dem::RunConfig rc = dem::load_config(root, DEM_SOURCE_DIR);
  EXPECT_DOUBLE_EQ(rc.scene.species[0].density, 2650.0);
  EXPECT_GT(rc.scene.particle_particle.friction, 0.0);
  EXPECT_LT(rc.scene.particle_particle.friction, 0.6);
}

// The shipped rotating material names its particle model: a scene that names the file runs
// rotating grains with its rolling resistance.
TEST(dem_MaterialFileShipped, DrySandRotatingLoadsWithItsModel) {
  YAML::Node root = YAML::Load(kScene);
  root["materials"]["sand"]["file"] = "configs/materials/dry_sand_rotating.yaml";
  const dem::RunConfig rc = dem::load_config(root, DEM_SOURCE_DIR);
  EXPECT_DOUBLE_EQ(rc.scene.species[0].density, 2650.0);
  EXPECT_TRUE(rc.scene.rotation.rotating());
  EXPECT_EQ(rc.scene.rotation.rolling.kind, dem::RollingResistance::Kind::epsd);
  EXPECT_GT(rc.scene.rotation.rolling.friction, 0.0);
  EXPECT_LE(rc.scene.rotation.rolling.friction, 1.0);
  EXPECT_GT(rc.scene.particle_particle.friction, 0.0);
  EXPECT_LT(rc.scene.particle_particle.friction, 0.6);
}

}  // namespace
