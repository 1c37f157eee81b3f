// prescribed_adapter [CONFIG.yaml] [--set dotted.key=value ...] [--name NAME] [--bus URL] ...
// Plays tool trajectories (keyframes or CSV) as kinematic outputs and records the wrenches it
// receives; docs/prescribed.md.
#include <cstdio>
#include <iostream>

#include "cosim/yaml_config.hpp"
#include "prescribed_adapter.hpp"

int main(int argc, char** argv) {
  // Several processes share one log: a line must reach it in one write, not one per <<.
  std::setvbuf(stderr, nullptr, _IOLBF, 1 << 14);
  try {
    auto args = cosim::parse_participant_args(argc, argv, false);
    prescribed::PrescribedAdapter model(args.config, args.config_dir);
    return cosim::run_participant(model, "prescribed", static_cast<int>(args.rest.size()),
                                  args.rest.data());
  } catch (const cosim::config::ConfigError& e) {
    std::cerr << "prescribed_adapter: config error: " << e.what() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << cosim::out_of_memory_message("prescribed_adapter") << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "prescribed_adapter: error: " << e.what() << "\n";
    return 1;
  }
}
