#include "cosim/files.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <ostream>
#include <sstream>
#include <filesystem>
#include <stdexcept>

#include "cosim/yaml_config.hpp"

namespace cosim {

namespace fs = std::filesystem;

namespace {

std::string quoted(const NamedFile& f) { return f.what + " '" + f.path + "'"; }

fs::path canonical_or_normal(const std::string& p) {
  std::error_code ec;
  fs::path c = fs::weakly_canonical(fs::absolute(p, ec), ec);
  if (ec) c = fs::absolute(p).lexically_normal();
  return c;
}

}  // namespace

bool same_file(const std::string& a, const std::string& b) {
  if (a.empty() || b.empty()) return false;
  struct stat sa{}, sb{};
  const bool ea = ::stat(a.c_str(), &sa) == 0, eb = ::stat(b.c_str(), &sb) == 0;
  if (ea && eb) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
  if (ea != eb) return false;  // one exists and the other does not
  return canonical_or_normal(a) == canonical_or_normal(b);
}

void check_output_files(const std::vector<NamedFile>& outputs, const std::vector<NamedFile>& inputs,
                        bool require_folders) {
  using config::ConfigError;
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    const NamedFile& o = outputs[i];
    if (o.path.empty()) continue;
    std::error_code ec;
    if (fs::is_directory(o.path, ec))
      throw ConfigError(quoted(o) + " is a folder: name a file in it (e.g. " +
                        (fs::path(o.path) / "out.h5").string() + ")");
    fs::path folder = fs::path(o.path).parent_path();
    if (folder.empty()) folder = ".";
    if (require_folders && !fs::is_directory(folder, ec))
      throw ConfigError(quoted(o) + ": the folder '" + folder.string() +
                        "' does not exist: create it or choose another path");
    for (std::size_t j = 0; j < i; ++j)
      if (same_file(o.path, outputs[j].path))
        throw ConfigError(quoted(outputs[j]) + " and " + quoted(o) +
                          " are the same file: both would write it and leave it unreadable; "
                          "give them different names");
    for (const NamedFile& in : inputs)
      if (same_file(o.path, in.path))
        throw ConfigError(quoted(o) + " is the same file as " + quoted(in) +
                          ", which this run reads: writing it would destroy the input; "
                          "choose another output name");
  }
}

namespace {

// "<folder>/.<name><suffix>" beside `path`.
std::string beside(const std::string& path, const std::string& suffix) {
  const fs::path p(path);
  std::string name = ".";
  name += p.filename().string();
  name += suffix;
  return (p.parent_path() / name).string();
}

std::string pid_suffix() { return std::to_string(static_cast<long>(::getpid())); }

}  // namespace

StagedFile::StagedFile(std::string path) : path_(std::move(path)) {
  temp_ = beside(path_, ".partial-" + pid_suffix());
}

StagedFile::StagedFile(InPlace, std::string path) : path_(std::move(path)), committed_(true) {
  earlier_ = beside(path_, ".previous-" + pid_suffix());
  std::error_code ec;
  fs::copy_file(path_, earlier_, fs::copy_options::overwrite_existing, ec);
  if (ec) {
    std::remove(earlier_.c_str());
    throw std::runtime_error("cannot keep a copy of '" + path_ + "' as '" + earlier_ +
                             "' before continuing it: " + ec.message() +
                             " (the copy is what a failed write would put back; free space on its disk)");
  }
}

StagedFile::~StagedFile() {
  if (!committed_) std::remove(temp_.c_str());
  else done();
}

void StagedFile::commit() {
  if (committed_) return;
  // The earlier file of this name stays reachable (a second name for the same inode) until the
  // new one is closed: done() drops it, restore() puts it back.
  const std::string keep = beside(path_, ".previous-" + pid_suffix());
  std::remove(keep.c_str());
  struct stat st{};
  bool kept = false;
  if (::stat(path_.c_str(), &st) == 0 && S_ISREG(st.st_mode)) {
    kept = ::link(path_.c_str(), keep.c_str()) == 0;
    // A file system without hard links: move it aside instead (the name is empty for a moment).
    if (!kept) kept = std::rename(path_.c_str(), keep.c_str()) == 0;
  }
  if (std::rename(temp_.c_str(), path_.c_str()) != 0) {
    const int err = errno;
    if (kept && ::stat(path_.c_str(), &st) != 0) std::rename(keep.c_str(), path_.c_str());
    else if (kept) std::remove(keep.c_str());
    throw std::runtime_error("cannot rename '" + temp_ + "' to '" + path_ +
                             "': " + std::strerror(err) +
                             " (is the folder writable, or is the output a folder?)");
  }
  if (kept) earlier_ = keep;
  committed_ = true;
}

void StagedFile::done() {
  if (resolved_) return;
  resolved_ = true;
  if (!committed_) return;
  if (!earlier_.empty()) std::remove(earlier_.c_str());
  earlier_.clear();
}

std::string StagedFile::restore() {
  if (resolved_) return "";
  resolved_ = true;
  if (!committed_) {
    std::remove(temp_.c_str());
    return "'" + path_ + "' was not replaced";
  }
  if (!earlier_.empty()) {
    const std::string earlier = earlier_;
    earlier_.clear();
    if (std::rename(earlier.c_str(), path_.c_str()) == 0)
      return "the earlier '" + path_ + "' is back in place";
    return "the earlier file is kept as '" + earlier + "' (it could not be renamed back: " +
           std::strerror(errno) + ")";
  }
  std::remove(path_.c_str());
  return "there was no earlier '" + path_ + "'; this run's incomplete file was removed";
}

// ---------------------------------------------------------------------------------------------

namespace {

std::string host_name() {
  char buf[256] = {};
  if (::gethostname(buf, sizeof buf - 1) != 0) return "unknown-host";
  return buf;
}

std::string now_text() {
  const std::time_t t = std::time(nullptr);
  char buf[64];
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

// "pid <n> on host <h> (<program>, since <t>)" from a lock file's text.
std::string holder(const std::string& text) {
  std::istringstream in(text);
  std::string key, pid = "?", host = "?", program = "?", since = "?";
  std::string line;
  while (std::getline(in, line)) {
    const auto eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string k = line.substr(0, eq), v = line.substr(eq + 1);
    if (k == "pid") pid = v;
    else if (k == "host") host = v;
    else if (k == "program") program = v;
    else if (k == "since") since = v;
  }
  return program + " pid " + pid + " on host " + host + " (since " + since + ")";
}

std::string read_all(int fd) {
  std::string text;
  char buf[512];
  ::lseek(fd, 0, SEEK_SET);
  for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) text.append(buf, static_cast<std::size_t>(n));
  return text;
}

}  // namespace

OutputLock::OutputLock(const NamedFile& output, const std::string& program) {
  // Beside the file the path names (a symbolic link leads to its target's lock).
  lock_path_ = beside(canonical_or_normal(output.path).string(), ".lock");
  for (int attempt = 0; attempt < 5; ++attempt) {
    const int fd = ::open(lock_path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0)
      throw config::ConfigError(quoted(output) + ": cannot create its lock file '" + lock_path_ +
                                "': " + std::strerror(errno) + " (is the folder writable?)");
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      const std::string text = read_all(fd);
      ::close(fd);
      if (err == EWOULDBLOCK)
        throw OutputBusy(quoted(output) + " is being written by another run: " + holder(text) +
                         ". One output file has one writer: wait for that run to end, stop it, or "
                         "choose another output name (lock file '" + lock_path_ + "')");
      throw config::ConfigError(quoted(output) + ": cannot lock '" + lock_path_ + "': " +
                                std::strerror(err));
    }
    // Locked: still the file of that name? (Its holder may have removed it just before.)
    struct stat by_fd{}, by_name{};
    if (::fstat(fd, &by_fd) != 0 || ::stat(lock_path_.c_str(), &by_name) != 0 ||
        by_fd.st_ino != by_name.st_ino || by_fd.st_dev != by_name.st_dev) {
      ::close(fd);
      continue;
    }
    const std::string text = read_all(fd);
    if (!text.empty())
      note_ = "took over the lock of " + quoted(output) + " left by " + holder(text) +
              ", which ended without removing it ('" + lock_path_ + "')";
    const std::string mine = "pid=" + std::to_string(static_cast<long>(::getpid())) + "\nhost=" +
                             host_name() + "\nprogram=" + program + "\nsince=" + now_text() +
                             "\noutput=" + output.path + "\n";
    if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, mine.data(), mine.size(), 0) != static_cast<ssize_t>(mine.size())) {
      const int err = errno;
      ::close(fd);
      throw config::ConfigError(quoted(output) + ": cannot write its lock file '" + lock_path_ +
                                "': " + std::strerror(err));
    }
    fd_ = fd;
    return;
  }
  throw config::ConfigError(quoted(output) + ": its lock file '" + lock_path_ +
                            "' keeps being replaced: is another run starting on it?");
}

OutputLock::~OutputLock() {
  if (fd_ < 0) return;
  ::unlink(lock_path_.c_str());  // while still locked: a waiting run then sees a new file
  ::close(fd_);
}

std::vector<std::unique_ptr<OutputLock>> lock_outputs(const std::vector<NamedFile>& outputs,
                                                      const std::string& program,
                                                      std::ostream& notes) {
  std::vector<std::unique_ptr<OutputLock>> locks;
  for (const NamedFile& o : outputs) {
    if (o.path.empty()) continue;
    locks.push_back(std::make_unique<OutputLock>(o, program));
    if (!locks.back()->note().empty()) notes << program << ": " << locks.back()->note() << "\n";
  }
  return locks;
}

}  // namespace cosim
