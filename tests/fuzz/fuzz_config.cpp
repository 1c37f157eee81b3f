// libFuzzer target: the YAML config loaders. The first byte picks the reader; the rest is the
// config text (what a config file or a --set override holds):
//   0: the master's config (cosim::config::load_string + master::parse_config)
//   1: the DEM config (load_string + dem::load_config, check_dt, validate_state)
//   2: a --set override applied to a small config ("dotted.key=value" is the whole text)
//   3: a participant's parameters amending a DEM config (apply_overrides, as dem_service does)
// Refusals (ConfigError, and the std::invalid_argument / SimulationError the programs also
// report as refusals) are the expected outcome; anything else escaping is a crash.
//
// To keep each run small and on the parser: the DEM config's files are replaced by fixed ones
// written at start-up (every tools[].mesh is a 2-triangle STL, particles.checkpoint and
// motion.csv are dropped: the STL target fuzzes the mesh reader), and fill counts are capped
// at 500 particles.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <unistd.h>

#include "config.hpp"  // master
#include "cosim/yaml_config.hpp"
#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem/stability.hpp"
#include "dem/state.hpp"

namespace {

namespace fs = std::filesystem;
namespace cfg = cosim::config;

const std::string& work_dir() {
  static const std::string dir = [] {
    const fs::path d = fs::temp_directory_path() / ("cosim_fuzz_config_" + std::to_string(::getpid()));
    fs::create_directories(d);
    std::ofstream(d / "tool.stl") << "solid t\n"
                                     "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
                                     "facet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\n"
                                     "endsolid t\n";
    return d.string();
  }();
  return dir;
}

// Points the config's file names at the fixed files and caps the particle counts.
void tame(YAML::Node root) {
  if (!root.IsMap()) return;
  if (YAML::Node tools = root["tools"]; tools && tools.IsSequence())
    for (std::size_t i = 0; i < tools.size(); ++i)
      if (tools[i].IsMap()) {
        if (tools[i]["mesh"]) tools[i]["mesh"] = "tool.stl";
        if (YAML::Node m = tools[i]["motion"]; m && m.IsMap() && m["csv"]) m.remove("csv");
      }
  if (YAML::Node p = root["particles"]; p && p.IsMap()) {
    if (p["checkpoint"]) p.remove("checkpoint");
    if (YAML::Node f = p["fill"]; f && f.IsSequence())
      for (std::size_t i = 0; i < f.size(); ++i)
        if (f[i].IsMap() && f[i]["count"] && f[i]["count"].IsScalar()) {
          long long n = 0;
          if (YAML::convert<long long>::decode(f[i]["count"], n) && n > 500) f[i]["count"] = 500;
        }
  }
  // Outputs are never written here (load_config does not write), but keep names harmless.
  if (YAML::Node o = root["output"]; o && o.IsMap()) o.remove("checkpoint");
}

void dem_config(YAML::Node root) {
  tame(root);
  dem::RunConfig rc = dem::load_config(root, work_dir());
  std::ostringstream warn;
  dem::check_dt(rc.scene, warn);
  dem::validate_state(rc.scene, rc.state, !rc.continues);
}

const char* kDemBase = R"(
scene: {dt: 1.0e-5}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact: {particle_particle: {normal_stiffness: 4.0e7, restitution: 0.3, friction: 0.5}}
tools: [{name: blade, mesh: tool.stl}]
particles: {list: [{species: grain, position: [0, 0, 0.1]}]}
)";

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const int which = data[0] % 4;
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    switch (which) {
      case 0:
        master::parse_config(cfg::load_string(text, "fuzz.yaml"), text);
        break;
      case 1:
        dem_config(cfg::load_string(text, "fuzz.yaml"));
        break;
      case 2: {
        YAML::Node root = cfg::load_string(kDemBase, "base.yaml");
        cfg::apply_override(root, text);
        dem_config(root);
        break;
      }
      default: {
        YAML::Node root = cfg::load_string(kDemBase, "base.yaml");
        const YAML::Node params = cfg::load_string(text, "parameters");
        cfg::apply_overrides(root, params, "participants.dem.parameters");
        dem_config(root);
        break;
      }
    }
  } catch (const cfg::ConfigError&) {
  } catch (const std::invalid_argument&) {
  } catch (const dem::SimulationError&) {
  }
  return 0;
}
