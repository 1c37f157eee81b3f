// Starts the participants a config asks the master to launch, watches them while the run
// goes on, and stops them at the end. Programs are looked up beside cosim_master, then PATH.
#pragma once

#include <sys/types.h>

#include <map>
#include <string>
#include <vector>

#include "config.hpp"

namespace master {

class Launcher {
 public:
  ~Launcher();
  // Starts `spec.launch` with --name, --bus and --session appended (it joins only that
  // session); raises ConfigError if the program is not found.
  void start(const ParticipantSpec& spec, const std::string& bus_url, int64_t session);
  // Raises cosim::LinkError naming a launched participant that has exited.
  void check() ;
  // Waits up to `grace` seconds for the participants to exit, then terminates them.
  void stop(double grace);

 private:
  struct Child { std::string name; pid_t pid; bool exited = false; int status = 0; };
  std::vector<Child> children_;
};

std::string find_program(const std::string& program);

}  // namespace master
