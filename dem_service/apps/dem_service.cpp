// dem_service CONFIG.yaml [--set dotted.key=value ...] [--name NAME] [--bus URL]
//             [--idle-timeout SECONDS] [--wait SECONDS]
// The DEM soil as a co-simulation participant: one kinematic input and one wrench output per
// tool of CONFIG.yaml (the dem_run schema plus `service`, docs/dem_service.md). The master's
// `parameters` for this participant amend the config as --set does.
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "cosim/yaml_config.hpp"
#include "dem/engine.hpp"
#include "dem/service.hpp"

namespace {

void usage() {
  std::cerr << "usage: dem_service CONFIG.yaml [--set dotted.key=value ...] [--name NAME] [--bus URL]\n"
               "                   [--idle-timeout SECONDS] [--wait SECONDS]\n"
               "  Serves the DEM scene of CONFIG.yaml to a co-simulation master (docs/dem_service.md).\n";
}

int run(int argc, char** argv) {
  std::string config_path;
  std::vector<std::string> sets;
  std::vector<char*> rest{argv[0]};
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "-h" || arg == "--help") {
      usage();
      return 0;
    } else if (arg == "--set") {
      if (a + 1 >= argc) {
        std::cerr << "dem_service: --set needs dotted.key=value\n";
        return 2;
      }
      sets.push_back(argv[++a]);
    } else if (!arg.empty() && arg[0] == '-') {
      rest.push_back(argv[a]);  // the participant's own options and their values
      if (a + 1 < argc && argv[a + 1][0] != '-') rest.push_back(argv[++a]);
    } else if (config_path.empty()) {
      config_path = arg;
    } else {
      std::cerr << "dem_service: more than one config file given ('" << arg << "')\n";
      return 2;
    }
  }
  if (config_path.empty()) {
    std::cerr << "dem_service: no config file given\n";
    usage();
    return 2;
  }
  YAML::Node root = cosim::config::load_file(config_path);
  for (const auto& s : sets) cosim::config::apply_override(root, s);
  dem::ServiceModel model(root, std::filesystem::path(config_path).parent_path().string());
  const int code = cosim::run_participant(model, "dem", static_cast<int>(rest.size()), rest.data());
  model.finish(std::cerr);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const cosim::config::ConfigError& e) {
    std::cerr << "dem_service: config error: " << e.what() << "\n";
    return 2;
  } catch (const std::invalid_argument& e) {
    std::cerr << "dem_service: refused: " << e.what() << "\n";
    return 2;
  } catch (const dem::SimulationError& e) {
    std::cerr << "dem_service: stopped: " << e.what() << "\n";
    return 3;
  } catch (const std::exception& e) {
    std::cerr << "dem_service: error: " << e.what() << "\n";
    return 1;
  }
}
