// hauler_adapter [CONFIG.yaml] [--set key=value ...] [--name NAME] [--bus URL] ...
// Serves the articulated-hauler model on the bus. CONFIG.yaml is the machine config
// (configs/hauler/machine.yaml; without it the built-in defaults, which equal that file);
// --set amends it; the master's participants.<name>.parameters amend it again.
#include <cstdio>
#include <cosim/yaml_config.hpp>

#include <iostream>

#include "hauler_model.hpp"

int main(int argc, char** argv) {
  // Several processes share one log: a line must reach it in one write, not one per <<.
  std::setvbuf(stderr, nullptr, _IOLBF, 1 << 14);
  cosim::ParticipantArgs args;
  try {
    args = cosim::parse_participant_args(argc, argv, false);
    hauler::read_parameters(args.config);  // refuse a bad file before joining any session
  } catch (const std::exception& e) {
    std::cerr << "hauler_adapter: " << (args.config_path.empty() ? "" : args.config_path + ": ")
              << e.what() << "\n"
              << "usage: hauler_adapter [CONFIG.yaml] [--set key=value ...] [--name NAME] "
                 "[--bus URL]\n";
    return 2;
  }
  hauler::HaulerModel model(args.config);
  return cosim::run_participant(model, "hauler", static_cast<int>(args.rest.size()),
                                args.rest.data());
}
