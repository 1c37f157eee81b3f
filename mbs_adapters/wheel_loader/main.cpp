// wheel_loader_adapter [CONFIG.yaml] [--set key=value ...] [--name NAME] [--bus URL] ...
// Serves the wheel-loader model on the bus. CONFIG.yaml is the machine config
// (configs/wheel_loader/machine.yaml; without it the built-in defaults, which equal that
// file); --set amends it; the master's participants.<name>.parameters amend it again.
#include "wheel_loader_adapter.hpp"

int main(int argc, char** argv) {
  return mbs::serve_machine(argc, argv, "wheel_loader_adapter", "wheel_loader", [](YAML::Node config) {
    return std::make_unique<wheel_loader::WheelLoaderAdapter>(std::move(config));
  });
}
