#include "run_key.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace master {

namespace {

bool set(const char* name) {
  const char* v = std::getenv(name);
  return v && *v;
}

// Writes all of `text` to fd; false on failure (errno set).
bool write_all(int fd, const std::string& text) {
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<std::size_t>(n);
  }
  return true;
}

std::string folder_for_unnamed_files() {
  if (const char* d = std::getenv("XDG_RUNTIME_DIR"); d && *d) return d;
  if (const char* d = std::getenv("TMPDIR"); d && *d) return d;
  return "/tmp";
}

}  // namespace

std::string key_hex(const cosim::auth::Key& key) {
  static const char* digits = "0123456789abcdef";
  std::string out;
  for (unsigned char c : key.bytes) out += digits[c >> 4], out += digits[c & 15];
  return out;
}

RunKey key_from_environment_or_log(const std::string& replay_log) {
  RunKey k;
  k.key = cosim::auth::key_from_environment();
  if (k.key) {
    k.source = RunKey::Source::environment;
    k.origin = set("COSIM_KEY_FILE") ? "$COSIM_KEY_FILE" : "$COSIM_KEY";
    return k;
  }
  std::error_code ec;
  if (!replay_log.empty() && std::filesystem::exists(replay_log + ".key", ec)) {
    k.key = cosim::auth::read_key_file(replay_log + ".key");
    k.source = RunKey::Source::recording;
    k.origin = replay_log + ".key";
  }
  return k;
}

void settle_run_key(RunKey& key, const Config& config, const std::vector<std::string>& hand_started) {
  if (!config.authenticate) {
    key = RunKey{};
    return;
  }
  if (key.key) return;
  if (hand_started.empty()) {
    key.key = cosim::auth::parse_key_hex(cosim::auth::new_key_hex(), "a new key");
    key.source = RunKey::Source::per_run;
    key.origin = "a fresh key for this run";
    return;
  }
  std::string names;
  for (std::size_t i = 0; i < hand_started.size(); ++i)
    names += (i == 0 ? "'" : i + 1 == hand_started.size() ? " and '" : ", '") + hand_started[i] + "'";
  throw cosim::config::ConfigError(
      "bus.authenticate: the bus of a run is authenticated, and " + names +
      (hand_started.size() == 1 ? " is" : " are") +
      " started by hand (no launch), so they need the run's key, and there is none: make one "
      "(cosim_master --new-key ~/.cosim/key), then give it to this master and to every participant "
      "started by hand as COSIM_KEY_FILE=~/.cosim/key in their environment (copy it to other hosts over "
      "a trusted channel, e.g. scp). Or let the master launch every participant "
      "(participants.<name>.launch): it then makes a fresh key for the run by itself. Or, on a "
      "host or network you trust, set bus.authenticate: false (any process that reaches the bus can "
      "then forge messages; the record's config says so) (docs/security.md)");
}

int key_as_unnamed_file(const cosim::auth::Key& key) {
  const std::string folder = folder_for_unnamed_files();
  int fd = ::open(folder.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd < 0) {  // a file system without O_TMPFILE: a named file, removed at once
    std::string path = folder + "/cosim_key_XXXXXX";
    fd = ::mkostemp(path.data(), O_CLOEXEC);
    if (fd < 0)
      throw std::runtime_error("cannot create the run's key file in " + folder + ": " + std::strerror(errno));
    ::unlink(path.c_str());
  }
  if (::fchmod(fd, 0600) != 0 || !write_all(fd, key_hex(key) + "\n")) {
    const int err = errno;
    ::close(fd);
    throw std::runtime_error("cannot write the run's key file in " + folder + ": " + std::strerror(err));
  }
  return fd;
}

std::string key_to_private_folder(int key_fd) {
  std::string text(256, '\0');
  std::size_t got = 0;
  while (got < text.size()) {
    const ssize_t n = ::pread(key_fd, text.data() + got, text.size() - got, static_cast<off_t>(got));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw std::runtime_error(std::string("cannot read the run's key file: ") + std::strerror(errno));
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  text.resize(got);
  if (text.empty()) throw std::runtime_error("cannot read the run's key file: it is empty");
  std::string folder = folder_for_unnamed_files() + "/cosim_key_XXXXXX";
  if (!::mkdtemp(folder.data()))  // mode 0700
    throw std::runtime_error("cannot create a private folder for the run's key in " + folder_for_unnamed_files() +
                             ": " + std::strerror(errno));
  const std::string path = folder + "/key";
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  const bool ok = fd >= 0 && ::fchmod(fd, 0600) == 0 && write_all(fd, text);
  const int err = errno;
  if (fd >= 0) ::close(fd);
  if (!ok) {
    remove_private_key_folder(folder);
    throw std::runtime_error("cannot write the run's key to " + path + ": " + std::strerror(err));
  }
  return folder;
}

bool remove_private_key_folder(const std::string& folder) {
  if (folder.empty()) return true;
  const std::string path = folder + "/key";
  const bool file_gone = ::unlink(path.c_str()) == 0 || errno == ENOENT;
  const bool folder_gone = ::rmdir(folder.c_str()) == 0 || errno == ENOENT;
  return file_gone && folder_gone;
}

void save_key_file(const cosim::auth::Key& key, const std::string& path) {
  const std::string tmp = path + ".tmp" + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) throw std::runtime_error("cannot create '" + tmp + "': " + std::strerror(errno));
  const bool ok = ::fchmod(fd, 0600) == 0 && write_all(fd, key_hex(key) + "\n") && ::fsync(fd) == 0;
  const int err = errno;
  ::close(fd);
  if (!ok || ::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = ok ? errno : err;
    ::unlink(tmp.c_str());
    throw std::runtime_error("cannot write the key file '" + path + "': " + std::strerror(e));
  }
}

std::string describe(const RunKey& key) {
  switch (key.source) {
    case RunKey::Source::environment:
      return "bus authenticated: every message sealed with the key from " + key.origin +
             "; messages without it are dropped";
    case RunKey::Source::recording:
      return "bus authenticated: every message sealed with the recording's key from " + key.origin +
             "; messages without it are dropped";
    case RunKey::Source::per_run:
      return "bus authenticated: every message sealed with a fresh key for this run, which the launched "
             "participants inherit; messages without it are dropped";
    case RunKey::Source::none: break;
  }
  return "bus not authenticated (bus.authenticate: false): any process that reaches it can forge "
         "messages (docs/security.md)";
}

}  // namespace master
