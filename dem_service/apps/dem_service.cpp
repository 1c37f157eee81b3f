// dem_service CONFIG.yaml [--set dotted.key=value ...] [--name NAME] [--bus URL]
//             [--session HEX] [--idle-timeout SECONDS] [--wait SECONDS]
// The DEM soil as a co-simulation participant: one kinematic input and one wrench output per
// tool of CONFIG.yaml (the dem_run schema plus `service`, docs/dem_service.md). The master's
// `parameters` for this participant amend the config as --set does.
#include <cstdio>
#include <iostream>
#include <new>
#include <string>

#include "cosim/yaml_config.hpp"
#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem/service.hpp"

namespace {

void usage() {
  std::cerr << "usage: dem_service CONFIG.yaml [--set dotted.key=value ...] [--name NAME] [--bus URL]\n"
               "                   [--session HEX] [--idle-timeout SECONDS] [--wait SECONDS]\n"
               "  Serves the DEM scene of CONFIG.yaml to a co-simulation master (docs/dem_service.md).\n";
}

int run(int argc, char** argv) {
  for (int a = 1; a < argc; ++a)
    if (std::string(argv[a]) == "-h" || std::string(argv[a]) == "--help") {
      usage();
      return 0;
    }
  auto args = cosim::parse_participant_args(argc, argv, true);
  // May execute dem_service again (once) with the OpenMP wait variables set: before the bus.
  const std::string wait = dem::apply_thread_wait(dem::read_thread_wait(args.config), argv);
  std::cerr << "dem_service: idle threads wait " << wait << "\n";
  dem::read_pair_kernel_environment();  // a bad DEM_PAIR_KERNEL stops it before the bus
  dem::ServiceModel model(args.config, args.config_dir, args.config_path);
  const int code =
      cosim::run_participant(model, "dem", static_cast<int>(args.rest.size()), args.rest.data());
  model.finish(std::cerr);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  // Several processes share one log: a line must reach it in one write, not one per <<.
  std::setvbuf(stderr, nullptr, _IOLBF, 1 << 14);
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
  } catch (const std::bad_alloc&) {  // memory ran out after the checks (docs/dem.md#memory)
    std::cerr << "dem_service: out of memory (std::bad_alloc): the scene needs more memory than this "
                 "process may use; lower particles.fill counts or run where more memory is free\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "dem_service: error: " << e.what() << "\n";
    return 1;
  }
}
