// wheel_loader_adapter [CONFIG.yaml] [--set key=value ...] [--name NAME] [--bus URL] ...
// Serves the wheel-loader model on the bus. CONFIG.yaml is the machine config
// (configs/wheel_loader/machine.yaml; without it the built-in defaults, which equal that
// file); --set amends it; the master's participants.<name>.parameters amend it again.
#include <cstdio>
#include <cosim/yaml_config.hpp>

#include <iostream>

#include "wheel_loader_model.hpp"

int main(int argc, char** argv) {
  // Several processes share one log: a line must reach it in one write, not one per <<.
  std::setvbuf(stderr, nullptr, _IOLBF, 1 << 14);
  cosim::ParticipantArgs args;
  try {
    args = cosim::parse_participant_args(argc, argv, false);
    wheel_loader::read_parameters(args.config);  // refuse a bad file before joining any session
  } catch (const std::exception& e) {
    std::cerr << "wheel_loader_adapter: " << (args.config_path.empty() ? "" : args.config_path + ": ")
              << e.what() << "\n"
              << "usage: wheel_loader_adapter [CONFIG.yaml] [--set key=value ...] [--name NAME] "
                 "[--bus URL]\n";
    return 2;
  }
  wheel_loader::WheelLoaderModel model(args.config);
  return cosim::run_participant(model, "wheel_loader", static_cast<int>(args.rest.size()),
                                args.rest.data());
}
