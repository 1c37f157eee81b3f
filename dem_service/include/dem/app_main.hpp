#pragma once
// The main() of the DEM's programs (dem_run, dem_service): standard error line-buffered
// (several processes share one log: a line must reach it in one write, not one per <<) and
// every error that reaches main turned into one line naming the program, with its exit code:
//   2  a config error or a refused input (cosim::config::ConfigError, std::invalid_argument)
//   3  a simulation that stopped (dem::SimulationError: unstable, a contact overflow, ...)
//   1  out of memory (std::bad_alloc) or any other error.
// docs/dem.md lists the exit codes (under "dem_run").

namespace dem {

int app_main(const char* program, int argc, char** argv, int (*run)(int, char**));

}  // namespace dem
