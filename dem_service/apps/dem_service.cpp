// dem_service CONFIG.yaml [--set dotted.key=value ...] [--name NAME] [--bus URL]
//             [--session HEX] [--idle-timeout SECONDS] [--wait SECONDS]
// The DEM soil as a co-simulation participant: one kinematic input and one wrench output per
// tool of CONFIG.yaml (the dem_run schema plus `service`, docs/dem_service.md). The master's
// `parameters` for this participant amend the config as --set does.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <new>
#include <stdexcept>
#include <string>

#include "cosim/yaml_config.hpp"
#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem/mpi/decomposed.hpp"
#include "dem/service.hpp"
#include "dem/thread_wait.hpp"

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
  // Several ranks are dem_run's only so far (docs/mpi.md): N copies would join the bus as N
  // participants. The mpi: section is validated and set aside as dem_run does.
  dem::mpi::take_options(args.config);
  if (const int ranks = dem::mpi::launched_ranks(); ranks > 1)
    throw std::invalid_argument(
        "mpi: dem_service does not run on several ranks yet (started with " +
        std::to_string(ranks) + "; docs/mpi.md): start it without mpirun, or run the scene with "
        "mpirun -np N dem_run");
  // May execute dem_service again (once) with the OpenMP wait variables set: before the bus.
  const std::string wait = dem::apply_thread_wait(dem::read_thread_wait(args.config), argv);
  std::cerr << "dem_service: idle threads wait " << wait << "\n";
  // The engine's performance options, once (a bad DEM_PAIR_KERNEL stops it before the bus).
  const dem::EngineOptions engine = dem::EngineOptions::from_environment();
  dem::ServiceModel model(args.config, args.config_dir, args.config_path, engine);
  // Where the OpenMP threads may run (their affinity masks): every core they were given.
  int threads = 1;
  if (const YAML::Node t = args.config["scene"]["threads"]) threads = std::max(1, t.as<int>());
  std::cerr << "dem_service: " << dem::describe_thread_cpus(dem::thread_cpus(threads)) << "\n";
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
