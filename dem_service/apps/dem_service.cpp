// dem_service CONFIG.yaml [--set dotted.key=value ...] [--name NAME] [--bus URL]
//             [--session HEX] [--idle-timeout SECONDS] [--wait SECONDS]
// The DEM soil as a co-simulation participant: one kinematic input and one wrench output per
// tool of CONFIG.yaml (the dem_run schema plus `service`, docs/dem_service.md). The master's
// `parameters` for this participant amend the config as --set does.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "cosim/yaml_config.hpp"
#include "dem/app_main.hpp"
#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem/mpi/decomposed.hpp"
#include "dem/mpi/service_ranks.hpp"
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
  // The mpi: section (docs/mpi.md), validated on any rank count and set aside as dem_run does.
  const dem::mpi::Options mpi_options = dem::mpi::take_options(args.config);
  // May execute dem_service again (once) with the OpenMP wait variables set: before the bus.
  const std::string wait = dem::apply_thread_wait(dem::read_thread_wait(args.config), argv);
  // Started by mpirun: MPI from here on (after the re-execution above). One rank is today's
  // program; on N > 1 rank 0 alone is the participant and the others follow it (docs/mpi.md).
  std::optional<dem::mpi::Session> mpi;
  if (dem::mpi::launched_by_mpirun()) mpi.emplace(&argc, &argv);
  const int rank = mpi ? mpi->rank() : 0, ranks = mpi ? mpi->size() : 1;
  if (rank != 0) std::freopen("/dev/null", "w", stderr);  // rank 0 speaks for all
  std::cerr << "dem_service: idle threads wait " << wait << "\n";
  // The engine's performance options, once (a bad DEM_PAIR_KERNEL stops it before the bus).
  const dem::EngineOptions engine = dem::EngineOptions::from_environment();
  if (ranks == 1) {
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
  // N > 1: the start-up checks agreed by every rank (the same config: the same answer), so
  // that a refusal ends every rank before rank 0 joins the bus.
  std::unique_ptr<dem::RankDriver> driver = dem::mpi::make_rank_driver(mpi_options);
  std::unique_ptr<dem::ServiceModel> model;
  int code = 0;
  std::string refusal;
  try {
    model = std::make_unique<dem::ServiceModel>(args.config, args.config_dir, args.config_path, engine);
    model->set_ranks(driver.get());
  } catch (const std::exception& e) {
    code = dynamic_cast<const std::invalid_argument*>(&e) || dynamic_cast<const cosim::config::ConfigError*>(&e) ? 2 : 1;
    refusal = e.what();
  }
  if (const int all = dem::mpi::Session::max_over_ranks(code); all != 0) {
    if (rank == 0) {
      if (code != 0)
        std::cerr << "dem_service: refused: " << refusal << "\n";
      else
        std::cerr << "dem_service: refused: another rank could not load the config\n";
    }
    return all;
  }
  if (rank != 0) {
    try {
      dem::mpi::follow(*model);
    } catch (const std::exception& e) {
      // Outside an agreed command (a broken command from rank 0): rank 0 would wait for this
      // rank in the next collective, so all end here, as dem_run's ranks do.
      std::fprintf(stdout, "dem_service: rank %d stopped: %s\n", rank, e.what());
      std::fflush(stdout);
      dem::mpi::Session::abort(1);
    }
    model->finish(std::cerr);
    return 0;
  }
  std::cerr << "dem_service: " << ranks << " ranks; rank 0 is the participant on the bus\n";
  dem::mpi::LeadModel lead(*model);
  int result = 1;
  try {
    result = cosim::run_participant(lead, "dem", static_cast<int>(args.rest.size()), args.rest.data());
  } catch (...) {
    dem::mpi::end_followers();
    throw;
  }
  dem::mpi::end_followers();
  model->finish(std::cerr);
  return result;
}

}  // namespace

int main(int argc, char** argv) { return dem::app_main("dem_service", argc, argv, run); }
