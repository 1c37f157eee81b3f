#include "dem/app_main.hpp"

#include <cstdio>
#include <iostream>
#include <new>
#include <stdexcept>

#include "cosim/yaml_config.hpp"
#include "dem/engine_types.hpp"

namespace dem {

int app_main(const char* program, int argc, char** argv, int (*run)(int, char**)) {
  std::setvbuf(stderr, nullptr, _IOLBF, 1 << 14);
  try {
    return run(argc, argv);
  } catch (const cosim::config::ConfigError& e) {
    std::cerr << program << ": config error: " << e.what() << "\n";
    return 2;
  } catch (const std::invalid_argument& e) {
    std::cerr << program << ": refused: " << e.what() << "\n";
    return 2;
  } catch (const SimulationError& e) {
    std::cerr << program << ": stopped: " << e.what() << "\n";
    return 3;
  } catch (const std::bad_alloc&) {  // memory ran out after the checks (docs/dem.md#memory)
    std::cerr << program << ": out of memory (std::bad_alloc): the scene needs more memory than "
                 "this process may use; lower particles.fill counts or run where more memory is "
                 "free\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << program << ": error: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace dem
