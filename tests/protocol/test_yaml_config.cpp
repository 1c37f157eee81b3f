#include <cosim/time.hpp>
#include <filesystem>
#include <cosim/yaml_config.hpp>
#include <gtest/gtest.h>

using namespace cosim::config;

TEST(YamlConfig, OverridesCreateAndReplaceNestedKeys) {
  YAML::Node root = YAML::Load("a: {b: 1}\n");
  apply_override(root, "a.b=2.5");
  apply_override(root, "a.c.d=[1, 2]");
  EXPECT_EQ(root["a"]["b"].as<double>(), 2.5);
  EXPECT_EQ(root["a"]["c"]["d"].size(), 2u);
  EXPECT_THROW(apply_override(root, "a.b"), ConfigError);
  EXPECT_THROW(apply_override(root, "a..b=1"), ConfigError);
  EXPECT_THROW(apply_override(root, "a.b.c=1"), ConfigError);  // a.b is a number, not a map
  YAML::Node list = YAML::Load("l: [{o: 1}, {o: 2}]");
  apply_override(list, "l.1.o=5");
  EXPECT_EQ(list["l"][1]["o"].as<int>(), 5);
  EXPECT_THROW(apply_override(list, "l.2.o=5"), ConfigError);
}

TEST(YamlConfig, OverrideMapsAmendAConfigAndNameTheirSource) {
  YAML::Node root = YAML::Load("contact: {k: 1, mu: 0.5}\nlist: [1, 2]\n");
  apply_overrides(root, YAML::Load("{contact.k: 4.0e8, list: [3, 4, 5], new.x: {a: 1}}"),
                  "participants.dem.parameters");
  EXPECT_EQ(root["contact"]["k"].as<double>(), 4e8);
  EXPECT_EQ(root["contact"]["mu"].as<double>(), 0.5);
  EXPECT_EQ(root["list"].size(), 3u);
  EXPECT_EQ(root["new"]["x"]["a"].as<int>(), 1);
  apply_overrides(root, YAML::Load("{contact: {mu: 0.3}}"), "nested");  // amends, keeps k
  EXPECT_EQ(root["contact"]["mu"].as<double>(), 0.3);
  EXPECT_EQ(root["contact"]["k"].as<double>(), 4e8);
  apply_overrides(root, YAML::Node(), "empty");  // no parameters: nothing changes
  EXPECT_EQ(root["contact"]["k"].as<double>(), 4e8);
  try {
    apply_overrides(root, YAML::Load("{contact.k.z: 1}"), "participants.dem.parameters");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("participants.dem.parameters: --set contact.k.z"),
              std::string::npos) << e.what();
  }
  EXPECT_THROW(apply_overrides(root, YAML::Load("[1, 2]"), "p"), ConfigError);
}

TEST(YamlConfig, UnknownKeysAreNamedWithTheAllowedOnes) {
  YAML::Node n = YAML::Load("mass: 1\nmas: 2\n");
  try {
    check_keys(n, "participants.mass1.parameters", {"mass", "stiffness"});
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_STREQ(e.what(), "participants.mass1.parameters.mas: unknown key 'mas' (allowed: mass, stiffness); did you mean 'mass'?");
  }
}

TEST(YamlConfig, UnknownKeysSuggestTheOnlyCloseAllowedKey) {
  const std::vector<std::string> scene{"dt", "gravity", "broad_phase_interval", "skin", "guard",
                                       "threads", "min_particles_per_thread", "stability"};
  EXPECT_EQ(closest_key("thread", scene), "threads");                 // deletion
  EXPECT_EQ(closest_key("gravty", scene), "gravity");                 // deletion in a long key
  EXPECT_EQ(closest_key("broad_phase_intervall", scene), "broad_phase_interval");
  EXPECT_EQ(closest_key("skni", scene), "");                          // two edits in a short key
  EXPECT_EQ(closest_key("GUARD", scene), "guard");                    // case ignored
  EXPECT_EQ(closest_key("gaurd", scene), "");                         // a swap is two edits
  EXPECT_EQ(closest_key("time_step", scene), "");                     // a different word
  EXPECT_EQ(closest_key("ab", {"a", "b", "abc"}), "");                // three at one edit: no guess
  EXPECT_EQ(closest_key("mass", {"mass"}), "mass");

  YAML::Node n = YAML::Load("frction: 0.5\n");
  try {
    check_keys(n, "contact.particle_particle", {"normal_stiffness", "restitution", "friction"});
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_STREQ(e.what(),
                 "contact.particle_particle.frction: unknown key 'frction' (allowed: "
                 "normal_stiffness, restitution, friction); did you mean 'friction'?");
  }
  try {
    check_keys(YAML::Load("time_step: 1\n"), "scene", {"dt", "gravity"});
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_STREQ(e.what(), "scene.time_step: unknown key 'time_step' (allowed: dt, gravity)");
  }
}

TEST(YamlConfig, TimesAreWholeNanoseconds) {
  EXPECT_EQ(cosim::seconds_to_duration(1e-3, "t"), cosim::nanoseconds(1'000'000));
  EXPECT_EQ(cosim::seconds_to_duration(1.25e-4, "t"), cosim::nanoseconds(125'000));
  EXPECT_EQ(cosim::seconds_to_time_point(4e-4, "t"), cosim::time_point_ns(400'000));
  EXPECT_THROW(cosim::seconds_to_duration(1.5e-10, "t"), ConfigError);
  EXPECT_THROW(cosim::seconds_to_time_point(-1, "t"), ConfigError);
}

namespace {

std::string refusal(const std::string& text) {
  try {
    load_string(text, "c.yaml");
    return "";
  } catch (const ConfigError& e) {
    return e.what();
  }
}

}  // namespace

// What yaml-cpp accepts but no config means is refused, naming the file, line and the fix.
TEST(YamlConfig, FilesThatAreNotAMapOfKeysAreRefused) {
  EXPECT_EQ(refusal("a: 1\nb: {c: 2}\n"), "");
  EXPECT_EQ(refusal(""), "");  // empty: every key takes its default
  EXPECT_EQ(refusal("hello\n"),
            "c.yaml: expected a map of 'key: value' lines at the top level, got the single value "
            "'hello': is this the right file? (docs/config.md, docs/dem.md)");
  EXPECT_NE(refusal("[1, 2]\n").find("c.yaml: expected a map of 'key: value' lines at the top level, got a list"),
            std::string::npos);
  EXPECT_EQ(refusal("a: 1\nb:\n  c: 2\n  c: 3\n"),
            "c.yaml:4:3: duplicate key 'c' (first at line 3): a key may appear once in a map; "
            "remove or merge one of them");
  EXPECT_NE(refusal("l: [{x: 1, x: 2}]\n").find("duplicate key 'x'"), std::string::npos);
  EXPECT_NE(refusal("? [1, 2]\n: 3\n").find("c.yaml:1:3: a key must be a plain name, got a list"),
            std::string::npos);
  EXPECT_NE(refusal("a: [1, 2\n").find("c.yaml:"), std::string::npos);
  EXPECT_NE(refusal("a: [1, 2\n").find("not valid YAML"), std::string::npos);
}

TEST(YamlConfig, AFolderOrAMissingFileIsNamed) {
  const auto dir = std::filesystem::temp_directory_path() / "yaml_config_folder_test";
  std::filesystem::create_directories(dir);
  try {
    load_file(dir.string());
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("config file '" + dir.string() + "' is a folder, not a file"),
              std::string::npos) << e.what();
  }
  try {
    load_file((dir / "missing.yaml").string());
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.yaml': it does not exist"), std::string::npos) << e.what();
  }
}
