// Bad lab inputs (docs/soil_lab.md) are refused with a message that names the key and the fix,
// by the parsers and by dem_lab itself (exit code 2).
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "cosim/yaml_config.hpp"
#include "dem/lab/repose.hpp"
#include "dem/lab/triaxial.hpp"

namespace {

namespace lab = dem::lab;

const char* kGrains = R"(
grains:
  density: 2600
  radius: {min: 0.06, max: 0.075}
  contact: {normal_stiffness: 4.0e7, restitution: 0.3, friction: 0.5}
)";

std::string triaxial_error(const std::string& body) {
  try {
    lab::parse_triaxial(cosim::config::load_string(body, "test"));
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

std::string biaxial_error(const std::string& body) {
  try {
    lab::parse_biaxial(cosim::config::load_string(body, "test"));
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

std::string repose_error(const std::string& body) {
  try {
    lab::parse_repose(cosim::config::load_string(body, "test"));
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

void expect_has(const std::string& msg, std::initializer_list<const char*> parts) {
  EXPECT_FALSE(msg.empty()) << "accepted";
  for (const char* p : parts) EXPECT_NE(msg.find(p), std::string::npos) << msg << "\n  lacks: " << p;
}

TEST(dem_LabBadInput, GoodTriaxialConfigIsAccepted) {
  const std::string ok = std::string(kGrains) + "triaxial: {confining_pressures: [20.0e3, 10.0e3]}\n";
  EXPECT_EQ(triaxial_error(ok), "");
  const lab::TriaxialOptions o = lab::parse_triaxial(cosim::config::load_string(ok, "t"));
  ASSERT_EQ(o.confining.size(), 2u);
  EXPECT_EQ(o.confining[0], 10e3);  // sorted
  EXPECT_EQ(o.grains.law.friction, 0.5);
}

TEST(dem_LabBadInput, TriaxialValuesNamed) {
  const std::string g = kGrains;
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: [10.0e3, -5.0e3]}\n"),
             {"triaxial.confining_pressures.1", "> 0 Pa", "-5.0e3"});
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: [0]}\n"),
             {"triaxial.confining_pressures.0"});
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: [10.0e3, 10.0e3]}\n"),
             {"triaxial.confining_pressures", "twice"});
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: []}\n"),
             {"triaxial.confining_pressures", "missing or empty"});
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: [abc]}\n"),
             {"triaxial.confining_pressures.0", "Pa", "abc"});
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: [1.0e4], strain_rate: 0}\n"),
             {"triaxial.strain_rate", "> 0"});
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: [1.0e4], strain_rate: -1}\n"),
             {"triaxial.strain_rate"});
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: [1.0e4], inertial_number: 0.5}\n"),
             {"triaxial.inertial_number", "quasi-static"});
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: [1.0e4], servo_gain: 1.5}\n"),
             {"triaxial.servo_gain", "below 1"});
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: [1.0e4], max_axial_strain: 0.8}\n"),
             {"triaxial.max_axial_strain"});
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: [1.0e4], record_every: 0.1}\n"),
             {"triaxial.record_every", "fewer than 5 records"});
  expect_has(triaxial_error(g + "sample: {count: 10}\ntriaxial: {confining_pressures: [1.0e4]}\n"),
             {"sample.count", "10"});
  expect_has(triaxial_error(g + "sample: {initial_fraction: 0.5}\ntriaxial: {confining_pressures: [1.0e4]}\n"),
             {"sample.initial_fraction", "0.35"});
  expect_has(triaxial_error(g + "sample: {preparation_friction: -0.1}\ntriaxial: {confining_pressures: [1.0e4]}\n"),
             {"sample.preparation_friction", ">= 0"});
  expect_has(triaxial_error(g + "run: {threads: 0}\ntriaxial: {confining_pressures: [1.0e4]}\n"),
             {"run.threads"});
}

TEST(dem_LabBadInput, MissingAndUnknownKeysNamed) {
  const std::string g = kGrains;
  expect_has(triaxial_error(g), {"triaxial", "missing", "confining_pressures"});
  expect_has(triaxial_error("triaxial: {confining_pressures: [1.0e4]}\n"), {"grains", "missing"});
  expect_has(triaxial_error("grains: {density: 2600, radius: 0.05}\ntriaxial: {confining_pressures: [1.0e4]}\n"),
             {"grains.contact", "missing"});
  expect_has(triaxial_error("grains: {radius: 0.05, contact: {normal_stiffness: 1.0e7, restitution: 0.3}}\n"
                            "triaxial: {confining_pressures: [1.0e4]}\n"),
             {"grains.density", "missing"});
  expect_has(triaxial_error(g + "triaxial: {confining_presures: [1.0e4]}\n"),
             {"triaxial.confining_presures", "unknown key", "did you mean 'confining_pressures'"});
  expect_has(triaxial_error(g + "triaxal: {confining_pressures: [1.0e4]}\n"), {"triaxal", "unknown key"});
  // The grains' own values and the contact law's keys, by their dotted path.
  expect_has(triaxial_error("grains: {density: -1, radius: 0.05, contact: {normal_stiffness: 1.0e7, restitution: 0.3}}\n"
                            "triaxial: {confining_pressures: [1.0e4]}\n"),
             {"grains.density", "> 0"});
  expect_has(triaxial_error("grains: {density: 2600, radius: {min: 0.08, max: 0.05}, contact: {normal_stiffness: 1.0e7, restitution: 0.3}}\n"
                            "triaxial: {confining_pressures: [1.0e4]}\n"),
             {"grains.radius", "min <= max"});
  expect_has(triaxial_error("grains: {density: 2600, radius: 0.05, contact: {normal_stiffness: 1.0e7, restitution: 0.3, friction: -1}}\n"
                            "triaxial: {confining_pressures: [1.0e4]}\n"),
             {"grains.contact.friction"});
  expect_has(triaxial_error("grains: {density: 2600, radius: 0.05, contact: {normal_stiffness: 1.0e7}}\n"
                            "triaxial: {confining_pressures: [1.0e4]}\n"),
             {"grains.contact", "restitution"});
}

TEST(dem_LabBadInput, BiaxialValuesNamed) {
  // The biaxial test reads the triaxial's keys under `biaxial`; every message names biaxial.*.
  const std::string g = kGrains;
  const std::string ok = g + "biaxial: {confining_pressures: [1.0e4]}\n";
  EXPECT_EQ(biaxial_error(ok), "");
  const lab::TriaxialOptions o = lab::parse_biaxial(cosim::config::load_string(ok, "t"));
  EXPECT_TRUE(o.plane_strain);
  EXPECT_TRUE(o.first_peak);  // the biaxial's default peak: the first one
  EXPECT_FALSE(lab::parse_triaxial(cosim::config::load_string(g + "triaxial: {confining_pressures: [1.0e4]}\n", "t")).first_peak);
  EXPECT_FALSE(lab::parse_biaxial(cosim::config::load_string(g + "biaxial: {confining_pressures: [1.0e4], peak: max}\n", "t")).first_peak);
  expect_has(biaxial_error(g + "biaxial: {confining_pressures: [10.0e3, -5.0e3]}\n"),
             {"biaxial.confining_pressures.1", "> 0 Pa"});
  expect_has(biaxial_error(g + "biaxial: {confining_pressures: []}\n"),
             {"biaxial.confining_pressures", "missing or empty"});
  expect_has(biaxial_error(g + "biaxial: {confining_pressures: [1.0e4], inertial_number: 0.5}\n"),
             {"biaxial.inertial_number", "quasi-static"});
  expect_has(biaxial_error(g + "biaxial: {confining_pressures: [1.0e4], servo_gain: 1.5}\n"),
             {"biaxial.servo_gain", "below 1"});
  expect_has(biaxial_error(g + "biaxial: {confining_pressures: [1.0e4], max_axial_strain: 0.8}\n"),
             {"biaxial.max_axial_strain"});
  expect_has(biaxial_error(g + "biaxial: {confining_pressures: [1.0e4], record_every: 0.1}\n"),
             {"biaxial.record_every"});
  expect_has(biaxial_error(g + "biaxial: {confining_pressures: [1.0e4], strain_rate: 0}\n"),
             {"biaxial.strain_rate", "> 0"});
  expect_has(biaxial_error(g + "biaxial: {confining_pressures: [1.0e4], max_consolidation_steps: 10}\n"),
             {"biaxial.max_consolidation_steps"});
  expect_has(biaxial_error(g + "biaxial: {confining_pressures: [1.0e4], peak: highest}\n"),
             {"biaxial.peak", "'highest'", "first", "max"});
  expect_has(triaxial_error(g + "triaxial: {confining_pressures: [1.0e4], peak: [1]}\n"),
             {"triaxial.peak", "first", "max"});
  expect_has(biaxial_error(g + "biaxial: {confining_presures: [1.0e4]}\n"),
             {"biaxial.confining_presures", "unknown key", "did you mean 'confining_pressures'"});
  // A triaxial config is not a biaxial one (and the other way round).
  expect_has(biaxial_error(g + "triaxial: {confining_pressures: [1.0e4]}\n"), {"triaxial", "unknown key"});
  expect_has(biaxial_error(g), {"biaxial", "missing", "confining_pressures"});
  expect_has(triaxial_error(g + "biaxial: {confining_pressures: [1.0e4]}\n"), {"biaxial", "unknown key"});
  expect_has(biaxial_error(g + "sample: {count: 10}\nbiaxial: {confining_pressures: [1.0e4]}\n"),
             {"sample.count"});
  expect_has(biaxial_error(g + "sample: {aspect: 5}\nbiaxial: {confining_pressures: [1.0e4]}\n"),
             {"sample.aspect", "0.5 .. 4"});
  expect_has(biaxial_error(g + "sample: {thickness: 0}\nbiaxial: {confining_pressures: [1.0e4]}\n"),
             {"sample.thickness", "0.1 .. 1"});
  expect_has(biaxial_error(g + "  model: spinning\nbiaxial: {confining_pressures: [1.0e4]}\n"),
             {"grains.model"});
}

TEST(dem_LabBadInput, ReposeValuesNamed) {
  const std::string g = kGrains;
  EXPECT_EQ(repose_error(g + "repose: {count: 300}\n"), "");
  expect_has(repose_error(g), {"repose", "missing"});
  expect_has(repose_error(g + "repose: {count: 3}\n"), {"repose.count"});
  expect_has(repose_error(g + "repose: {lift_speed: -0.1}\n"), {"repose.lift_speed", ">= 0"});
  expect_has(repose_error(g + "repose: {cylinder_radius: 0.1}\n"), {"repose.cylinder_radius", "3 grain diameters"});
  expect_has(repose_error(g + "repose: {cylinder_radius: 1.0, base_radius: 1.5}\n"), {"repose.base_radius"});
  expect_has(repose_error(g + "repose: {max_time: 0}\n"), {"repose.max_time", "> 0"});
  expect_has(repose_error(g + "repose: {sectors: 0}\n"), {"repose.sectors"});
  expect_has(repose_error(g + "repose: {cont: 300}\n"), {"repose.cont", "unknown key", "did you mean 'count'"});
}

TEST(dem_LabBadInput, ParticleModelNamed) {
  // grains.model and grains.rolling_resistance: the engine's reader and checks, named by the
  // lab's keys (docs/soil_lab.md).
  const std::string t = "triaxial: {confining_pressures: [1.0e4]}\n";
  const std::string g = kGrains;
  const lab::TriaxialOptions ok = lab::parse_triaxial(cosim::config::load_string(
      g + "  model: rotating\n  rolling_resistance: {friction: 0.2, damping: 0.3}\n" + t, "t"));
  EXPECT_TRUE(ok.grains.rotation.rotating());
  EXPECT_EQ(ok.grains.rotation.rolling.kind, dem::RollingResistance::Kind::epsd);
  EXPECT_EQ(ok.grains.rotation.rolling.friction, 0.2);
  EXPECT_EQ(ok.grains.rotation.rolling.damping, 0.3);
  EXPECT_FALSE(lab::parse_triaxial(cosim::config::load_string(g + t, "t")).grains.rotation.rotating());
  EXPECT_FALSE(lab::parse_triaxial(cosim::config::load_string(g + "  model: translating\n" + t, "t"))
                   .grains.rotation.rotating());
  expect_has(triaxial_error(g + "  model: spinning\n" + t),
             {"grains.model", "'spinning' is not allowed", "rotating"});
  expect_has(triaxial_error(g + "  rolling_resistance: {friction: 0.2}\n" + t),
             {"grains.rolling_resistance", "grains.model: rotating"});
  expect_has(triaxial_error(g + "  model: rotating\n  rolling_resistance: {friction: -0.1}\n" + t),
             {"grains.rolling_resistance.friction", "> 0"});
  expect_has(triaxial_error(g + "  model: rotating\n  rolling_resistance: {friction: 1.5}\n" + t),
             {"grains.rolling_resistance.friction", "above 1"});
  expect_has(triaxial_error(g + "  model: rotating\n  rolling_resistance: {friction: 0.1, damping: 2}\n" + t),
             {"grains.rolling_resistance.damping", "[0, 1]"});
  expect_has(triaxial_error(g + "  model: rotating\n  rolling_resistance: {friction: 0.1, stiffness_factor: 0}\n" + t),
             {"grains.rolling_resistance.stiffness_factor", "> 0"});
  expect_has(triaxial_error(g + "  model: rotating\n  rolling_resistance: {frction: 0.1}\n" + t),
             {"grains.rolling_resistance.frction", "unknown key", "did you mean 'friction'"});
  expect_has(triaxial_error(g + "  model: rotating\n  rolling_resistance: 0.1\n" + t),
             {"grains.rolling_resistance", "expected a map"});
  expect_has(triaxial_error(g + "  modle: rotating\n" + t),
             {"grains.modle", "unknown key", "model"});
  // The same in the repose test.
  expect_has(repose_error(g + "  model: rolling\nrepose: {count: 300}\n"), {"grains.model"});
  expect_has(repose_error(g + "  model: rotating\n  rolling_resistance: {friction: 0}\nrepose: {count: 300}\n"),
             {"grains.rolling_resistance.friction"});
}

// dem_lab: the program refuses with exit code 2 and a message on stderr naming the key.
std::pair<int, std::string> run(const std::string& args) {
  const std::string cmd = std::string(DEM_LAB_EXE) + " " + args + " 2>&1";
  std::string out;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return {-1, ""};
  std::array<char, 512> buf;
  while (fgets(buf.data(), buf.size(), p)) out += buf.data();
  const int status = pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

TEST(dem_LabBadInput, ProgramRefusesWithExitCodeTwo) {
  const auto dir = std::filesystem::temp_directory_path() / "test_lab_bad_input";
  std::filesystem::create_directories(dir);
  const auto cfg = dir / "t.yaml";
  std::ofstream(cfg) << kGrains << "triaxial: {confining_pressures: [1.0e4]}\n";
  auto [rc, out] = run("triaxial " + cfg.string() + " --set 'triaxial.confining_pressures=[-1]' --out " +
                       (dir / "out").string() + " --no-plot");
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("triaxial.confining_pressures.0"), std::string::npos) << out;
  std::tie(rc, out) = run("shear " + cfg.string());
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("unknown test 'shear'"), std::string::npos) << out;
  std::tie(rc, out) = run("triaxial " + (dir / "missing.yaml").string());
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("missing.yaml"), std::string::npos) << out;
  std::tie(rc, out) = run("repose " + cfg.string() + " --no-plot");
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("unknown key 'triaxial'"), std::string::npos) << out;
  std::tie(rc, out) = run("triaxial " + cfg.string() + " --set grains.model=spinning --no-plot");
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("grains.model"), std::string::npos) << out;
  std::tie(rc, out) = run("triaxial " + cfg.string() +
                          " --set grains.model=rotating --set grains.rolling_resistance.friction=-1 --no-plot");
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("grains.rolling_resistance.friction"), std::string::npos) << out;
  // The biaxial test: a bad value under biaxial.*, and a triaxial config given to it.
  const auto bcfg = dir / "b.yaml";
  std::ofstream(bcfg) << kGrains << "biaxial: {confining_pressures: [1.0e4]}\n";
  std::tie(rc, out) = run("biaxial " + bcfg.string() + " --set biaxial.servo_gain=2 --out " +
                          (dir / "out").string() + " --no-plot");
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("biaxial.servo_gain"), std::string::npos) << out;
  std::tie(rc, out) = run("biaxial " + cfg.string() + " --no-plot");
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("unknown key 'triaxial'"), std::string::npos) << out;
  std::tie(rc, out) = run("triaxial " + cfg.string() + " --bogus");
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("--bogus"), std::string::npos) << out;
  std::filesystem::remove_all(dir);
}

}  // namespace
