// Starts the participants a config asks the master to launch, watches them while the run
// goes on, and stops them at the end. Programs are looked up beside cosim_master, then PATH.
#pragma once

#include <sys/types.h>
#include <unistd.h>

#include <map>
#include <string>
#include <vector>

#include "config.hpp"

namespace master {

class Launcher {
 public:
  ~Launcher();
  // Starts `spec.launch` with --name, --bus and --session appended (it joins only that
  // session); raises ConfigError if the program is not found. With spec.mpi.ranks > 0 it starts
  // `mpirun -np RANKS [-x COSIM_KEY_FILE] [-x COSIM_KEY] ARGS... PROGRAM ...` instead (the
  // program's full path), and the run's key reaches the ranks as a named file (share_key).
  void start(const ParticipantSpec& spec, const std::string& bus_url, int64_t session);
  // Raises ConfigError naming what start() would not find (the program, mpirun), so a config
  // is refused before anything is started.
  static void check_startable(const ParticipantSpec& spec);
  // The participants started from now on inherit `fd` (an open key file, run_key.hpp) and find
  // it as COSIM_KEY_FILE=/proc/self/fd/<fd> in their environment ($COSIM_KEY is removed there).
  // -1: they inherit the master's environment as it is. An MPI job (spec.mpi) cannot inherit a
  // descriptor through mpirun: it finds COSIM_KEY_FILE=<folder>/key, a copy of the key in a
  // folder of its own (mode 0700, the file 0600; run_key.hpp), which remove_key_files() removes.
  void share_key(int fd) { key_fd_ = fd; }
  // Removes the key file made for MPI jobs (if any): once every participant has joined (they
  // read the key as they open the bus), and at the latest when the launcher stops.
  void remove_key_files();
  // The folder of that key file while it exists, else "".
  const std::string& key_folder() const { return key_folder_; }
  // Whether the participants started from now on write through a line relay: every line they
  // write reaches the master's stdout or stderr whole, in one write(), so lines of several
  // processes sharing one log never interleave mid-line. Default: when stderr is not a terminal.
  void relay_lines(bool on) { relay_lines_ = on; }
  // Raises cosim::LinkError naming a launched participant that has exited.
  void check() ;
  // Waits up to `grace` seconds for the participants to exit, then sends SIGTERM to those
  // left and waits up to `term_grace` seconds more (they finish their outputs on SIGTERM),
  // then kills what is still running; each step is reported on stderr with the name.
  void stop(double grace, double term_grace = 5.0);
  // How a launched participant ended ("exited with code 0", "was killed by signal 9", "still
  // running"), or "not launched".
  std::string exit_description(const std::string& name) const;

 private:
  void wait_for_relays();

  struct Child { std::string name; pid_t pid; bool exited = false; int status = 0; };
  std::vector<Child> children_;
  std::vector<pid_t> relays_;  // the line relays of the participants' output
  bool relay_lines_ = !isatty(STDERR_FILENO);
  int key_fd_ = -1;
  std::string key_folder_;  // the MPI jobs' copy of the key (key_to_private_folder)
};

std::string find_program(const std::string& program);

}  // namespace master
