// hauler_adapter [CONFIG.yaml] [--set key=value ...] [--name NAME] [--bus URL] ...
// Serves the articulated-hauler model on the bus. CONFIG.yaml is the machine config
// (configs/hauler/machine.yaml; without it the built-in defaults, which equal that file);
// --set amends it; the master's participants.<name>.parameters amend it again.
#include "hauler_adapter.hpp"

int main(int argc, char** argv) {
  return mbs::serve_machine(argc, argv, "hauler_adapter", "hauler", [](YAML::Node config) {
    return std::make_unique<hauler::HaulerAdapter>(std::move(config));
  });
}
