// prescribed_participant [CONFIG.yaml] [--set dotted.key=value ...] [--name NAME] [--bus URL] ...
// Plays tool trajectories (keyframes or CSV) as kinematic outputs and records the wrenches it
// receives; docs/prescribed.md.
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "cosim/yaml_config.hpp"
#include "prescribed_model.hpp"

int main(int argc, char** argv) {
  try {
    std::string config_path;
    std::vector<std::string> sets;
    std::vector<char*> rest{argv[0]};
    for (int a = 1; a < argc; ++a) {
      const std::string arg = argv[a];
      if (arg == "--set" && a + 1 < argc) {
        sets.push_back(argv[++a]);
      } else if (!arg.empty() && arg[0] == '-') {
        rest.push_back(argv[a]);
        if (a + 1 < argc && argv[a + 1][0] != '-') rest.push_back(argv[++a]);
      } else if (config_path.empty()) {
        config_path = arg;
      } else {
        std::cerr << "prescribed_participant: more than one config file ('" << arg << "')\n";
        return 2;
      }
    }
    YAML::Node root = config_path.empty() ? YAML::Node(YAML::NodeType::Map)
                                          : cosim::config::load_file(config_path);
    for (const auto& s : sets) cosim::config::apply_override(root, s);
    const std::string base =
        config_path.empty() ? "" : std::filesystem::path(config_path).parent_path().string();
    prescribed::PrescribedModel model(root, base);
    return cosim::run_participant(model, "prescribed", static_cast<int>(rest.size()), rest.data());
  } catch (const cosim::config::ConfigError& e) {
    std::cerr << "prescribed_participant: config error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "prescribed_participant: error: " << e.what() << "\n";
    return 1;
  }
}
