#include "launcher.hpp"

#include <signal.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>
#include <poll.h>

#include <chrono>
#include <cstring>
#include <climits>
#include <cstdlib>
#include <iostream>
#include <thread>

#include "cosim/bus.hpp"
#include "cosim/stopwatch.hpp"
#include "run_key.hpp"

namespace master {

namespace {
bool executable(const std::string& path) {
  struct stat st {};
  return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && access(path.c_str(), X_OK) == 0;
}

std::string own_dir() {
  char buf[PATH_MAX];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (n <= 0) return ".";
  std::string p(buf, static_cast<std::size_t>(n));
  return p.substr(0, p.rfind('/'));
}

// The master's environment for a child; with a shared key (key_file not empty), COSIM_KEY_FILE
// names it (the inherited descriptor, or an MPI job's key file) and no other key variable is
// passed on.
std::vector<std::string> child_environment(const std::string& key_file) {
  std::vector<std::string> env;
  for (char** e = environ; e && *e; ++e) {
    const std::string v = *e;
    if (!key_file.empty() && (v.rfind("COSIM_KEY=", 0) == 0 || v.rfind("COSIM_KEY_FILE=", 0) == 0)) continue;
    env.push_back(v);
  }
  if (!key_file.empty()) env.push_back("COSIM_KEY_FILE=" + key_file);
  return env;
}

bool has_variable(const std::vector<std::string>& env, const std::string& name) {
  for (const auto& v : env)
    if (v.rfind(name + "=", 0) == 0) return true;
  return false;
}

// A process of its own (forked, no allocation) that copies what a participant writes to its
// stdout and stderr (the pipes `out` and `err`) to the master's, each complete line with one
// write(): the lines of the processes that share one log never interleave mid-line (a
// participant writes a line in pieces when its stderr is unbuffered). It outlives the master
// if need be and ends when the participant has closed both pipes.
struct LineRelay {
  int in = -1, out = -1;
  char buf[1 << 16];
  std::size_t n = 0;

  static void write_all(int fd, const char* p, std::size_t size) {
    while (size > 0) {
      const ssize_t w = ::write(fd, p, size);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) return;  // the log is gone: drain on, so the participant is not blocked
      p += w;
      size -= static_cast<std::size_t>(w);
    }
  }
  // Writes the complete lines held (all of it at the end, or when a line fills the buffer).
  void flush(bool all) {
    std::size_t end = n;
    if (!all) {
      while (end > 0 && buf[end - 1] != '\n') --end;
      if (end == 0 && n == sizeof buf) end = n;
    }
    write_all(out, buf, end);
    std::memmove(buf, buf + end, n - end);
    n -= end;
  }
  // Reads what is there; false at the end of the stream.
  bool read_some() {
    const ssize_t r = ::read(in, buf + n, sizeof buf - n);
    if (r < 0 && errno == EINTR) return true;
    if (r <= 0) {
      flush(true);
      return false;
    }
    n += static_cast<std::size_t>(r);
    flush(false);
    return true;
  }
};

[[noreturn]] void run_line_relay(int out_pipe, int err_pipe) {
  signal(SIGINT, SIG_IGN);  // a Ctrl-C for the run must not cut the participants' last words
  signal(SIGTERM, SIG_IGN);
  signal(SIGPIPE, SIG_IGN);
  for (int fd = 3; fd < 1024; ++fd)
    if (fd != out_pipe && fd != err_pipe) ::close(fd);
  static LineRelay relays[2];
  relays[0].in = out_pipe;
  relays[0].out = STDOUT_FILENO;
  relays[1].in = err_pipe;
  relays[1].out = STDERR_FILENO;
  bool open[2] = {true, true};
  while (open[0] || open[1]) {
    pollfd fds[2];
    for (int i = 0; i < 2; ++i) fds[i] = {open[i] ? relays[i].in : -1, POLLIN, 0};
    if (::poll(fds, 2, -1) < 0) {
      if (errno == EINTR) continue;
      break;
    }
    for (int i = 0; i < 2; ++i)
      if (open[i] && (fds[i].revents & (POLLIN | POLLHUP | POLLERR))) open[i] = relays[i].read_some();
  }
  _exit(0);
}

std::string describe_status(int status) {
  if (WIFEXITED(status)) return "exited with code " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return "was killed by signal " + std::to_string(WTERMSIG(status));
  return "stopped";
}
}  // namespace

std::string find_program(const std::string& program) {
  if (program.find('/') != std::string::npos) return executable(program) ? program : "";
  const std::string beside = own_dir() + "/" + program;
  if (executable(beside)) return beside;
  if (const char* path = std::getenv("PATH")) {
    std::string p = path;
    std::size_t start = 0;
    while (start <= p.size()) {
      const auto end = p.find(':', start);
      const std::string dir = p.substr(start, end - start);
      if (!dir.empty() && executable(dir + "/" + program)) return dir + "/" + program;
      if (end == std::string::npos) break;
      start = end + 1;
    }
  }
  return "";
}

Launcher::~Launcher() { stop(0.5, 2.0); }

void Launcher::check_startable(const ParticipantSpec& spec) {
  if (spec.launch.empty()) return;
  if (find_program(spec.launch[0]).empty())
    throw cosim::config::ConfigError("participants." + spec.name + ".launch: program '" + spec.launch[0] +
                                     "' not found beside cosim_master or on PATH; build it or give its path");
  if (spec.mpi.ranks > 0 && find_program(spec.mpi.mpirun).empty())
    throw cosim::config::ConfigError(
        "participants." + spec.name + ".mpi: '" + spec.mpi.mpirun + "' not found on PATH, so the " +
        std::to_string(spec.mpi.ranks) + "-rank job cannot be started: install an MPI (Debian: openmpi-bin "
        "libopenmpi-dev, scripts/setup.sh), name its launcher in mpi.mpirun, or drop mpi: to run the program "
        "as one process");
}

void Launcher::remove_key_files() {
  if (key_folder_.empty()) return;
  if (!remove_private_key_folder(key_folder_))
    std::cerr << "cosim_master: could not remove the MPI jobs' key folder " << key_folder_ << ": remove it by hand\n";
  key_folder_.clear();
}

void Launcher::start(const ParticipantSpec& spec, const std::string& bus_url, int64_t session) {
  check_startable(spec);
  const bool mpi = spec.mpi.ranks > 0;
  std::string key_file;  // what the participant finds in COSIM_KEY_FILE
  if (key_fd_ >= 0 && !mpi) key_file = "/proc/self/fd/" + std::to_string(key_fd_);
  if (key_fd_ >= 0 && mpi) {
    if (key_folder_.empty()) key_folder_ = key_to_private_folder(key_fd_);
    key_file = key_folder_ + "/key";
  }
  std::vector<std::string> env = child_environment(key_file);
  std::vector<std::string> args;
  if (mpi) {
    // mpirun passes its environment to the ranks on its own host; -x passes the key's variable
    // to ranks on other hosts too (rank 0, the one on the bus, needs it; docs/mpi.md).
    args = {find_program(spec.mpi.mpirun), "-np", std::to_string(spec.mpi.ranks)};
    for (const char* v : {"COSIM_KEY_FILE", "COSIM_KEY"})
      if (has_variable(env, v)) args.insert(args.end(), {"-x", v});
    args.insert(args.end(), spec.mpi.args.begin(), spec.mpi.args.end());
  }
  args.push_back(find_program(spec.launch[0]));
  args.insert(args.end(), spec.launch.begin() + 1, spec.launch.end());
  args.insert(args.end(), {"--name", spec.name, "--bus", bus_url, "--session", cosim::id_hex(session)});
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::vector<char*> envp;
  for (auto& e : env) envp.push_back(e.data());
  envp.push_back(nullptr);
  const int key_fd = mpi ? -1 : key_fd_;  // an MPI job reads the key file instead
  // The participant's stdout and stderr through a line relay (see relay_lines), unless the
  // master writes to a terminal (where a participant's own progress line stays live).
  int out_pipe[2] = {-1, -1}, err_pipe[2] = {-1, -1};
  const bool relay = relay_lines_ && ::pipe2(out_pipe, O_CLOEXEC) == 0 && ::pipe2(err_pipe, O_CLOEXEC) == 0;
  pid_t relay_pid = -1;
  if (relay) {
    relay_pid = fork();
    if (relay_pid == 0) {
      ::close(out_pipe[1]);
      ::close(err_pipe[1]);
      run_line_relay(out_pipe[0], err_pipe[0]);
    }
  }
  auto close_pipes = [&] {
    for (int fd : {out_pipe[0], out_pipe[1], err_pipe[0], err_pipe[1]})
      if (fd >= 0) ::close(fd);
  };
  const pid_t parent = getpid();
  const pid_t pid = relay && relay_pid < 0 ? -1 : fork();
  if (pid < 0) {
    close_pipes();
    throw std::runtime_error("cannot start participant " + spec.name + ": fork failed");
  }
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGTERM);  // no orphans if the master dies
    if (getppid() != parent) _exit(1);
    if (relay && (dup2(out_pipe[1], STDOUT_FILENO) < 0 || dup2(err_pipe[1], STDERR_FILENO) < 0)) _exit(126);
    if (key_fd >= 0 && fcntl(key_fd, F_SETFD, 0) != 0) _exit(126);  // inherited across exec
    execve(argv[0], argv.data(), envp.data());
    _exit(127);
  }
  close_pipes();
  if (relay_pid > 0) relays_.push_back(relay_pid);
  children_.push_back({spec.name, pid});
}

void Launcher::check() {
  for (auto& c : children_) {
    if (c.exited) continue;
    int status = 0;
    if (waitpid(c.pid, &status, WNOHANG) == c.pid) {
      c.exited = true;
      c.status = status;
      throw cosim::LinkError(c.name, "participant '" + c.name + "' (pid " + std::to_string(c.pid) + ") " +
                                         describe_status(status) + " during the run; see its messages above");
    }
  }
}

void Launcher::stop(double grace, double term_grace) {
  remove_key_files();  // read by now, or never needed: the run is over
  // Reaps every child that has exited; true when none is left.
  auto reap = [&] {
    bool all = true;
    for (auto& c : children_) {
      if (c.exited) continue;
      int status = 0;
      if (waitpid(c.pid, &status, WNOHANG) == c.pid) {
        c.exited = true;
        c.status = status;
      } else {
        all = false;
      }
    }
    return all;
  };
  // Polls until all have exited or `seconds` passed.
  auto wait_all = [&](double seconds) {
    const cosim::Stopwatch waited;
    while (!reap()) {
      if (waited.seconds() > seconds) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return true;
  };
  if (wait_all(grace)) return wait_for_relays();
  // Still running: ask them to stop (the participants finish their outputs on SIGTERM), all at
  // once, and give them term_grace to do it before they are killed.
  for (auto& c : children_)
    if (!c.exited) {
      std::cerr << "cosim_master: participant '" << c.name << "' (pid " << c.pid
                << ") did not exit within " << grace << " s of the end; sending SIGTERM\n";
      kill(c.pid, SIGTERM);
    }
  if (wait_all(term_grace)) return wait_for_relays();
  for (auto& c : children_)
    if (!c.exited) {
      std::cerr << "cosim_master: participant '" << c.name << "' (pid " << c.pid
                << ") did not exit within " << term_grace << " s of SIGTERM; killing it\n";
      kill(c.pid, SIGKILL);
      int status = 0;
      waitpid(c.pid, &status, 0);
      c.exited = true;
      c.status = status;
    }
  wait_for_relays();
}

void Launcher::wait_for_relays() {
  // A relay ends once its participant (and whatever inherited its output) has exited; a
  // descendant that lives on keeps it, and it is left to finish by itself.
  const cosim::Stopwatch waited;
  for (auto it = relays_.begin(); it != relays_.end();) {
    int status = 0;
    const pid_t r = waitpid(*it, &status, WNOHANG);
    if (r == *it || r < 0) {
      it = relays_.erase(it);
    } else if (waited.seconds() > 2.0) {
      ++it;
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
}

std::string Launcher::exit_description(const std::string& name) const {
  for (const auto& c : children_)
    if (c.name == name) return c.exited ? describe_status(c.status) : "still running";
  return "not launched";
}

}  // namespace master
