// wheel_loader_adapter [CONFIG.yaml] [--set key=value ...] [--name NAME] [--bus URL] ...
// Serves the wheel-loader model on the bus. CONFIG.yaml is the machine config
// (configs/wheel_loader/machine.yaml; without it the built-in defaults, which equal that
// file); --set amends it; the master's participants.<name>.parameters amend it again.
#include <cosim/yaml_config.hpp>

#include <cstring>
#include <iostream>

#include "wheel_loader_model.hpp"

int main(int argc, char** argv) {
  namespace cfg = cosim::config;
  std::vector<char*> rest{argv[0]};
  std::string config_path;
  std::vector<std::string> sets;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--set") == 0 && i + 1 < argc) {
      sets.emplace_back(argv[++i]);
    } else if (argv[i][0] != '-' && config_path.empty() &&
               (rest.size() == 1 || std::strncmp(rest.back(), "--", 2) != 0)) {
      config_path = argv[i];
    } else {
      rest.push_back(argv[i]);
    }
  }
  YAML::Node root(YAML::NodeType::Map);
  try {
    if (!config_path.empty()) root = cfg::load_file(config_path);
    if (!root || root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
    for (const auto& s : sets) cfg::apply_override(root, s);
    wheel_loader::read_parameters(root);  // refuse a bad file before joining any session
  } catch (const std::exception& e) {
    std::cerr << "wheel_loader_adapter: " << (config_path.empty() ? "" : config_path + ": ")
              << e.what() << "\n"
              << "usage: wheel_loader_adapter [CONFIG.yaml] [--set key=value ...] [--name NAME] "
                 "[--bus URL]\n";
    return 2;
  }
  wheel_loader::WheelLoaderModel model(root);
  return cosim::run_participant(model, "wheel_loader", static_cast<int>(rest.size()), rest.data());
}
