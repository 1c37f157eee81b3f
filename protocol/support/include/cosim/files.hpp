// Output files that never clobber anything by accident (docs/output.md#file-safety).
// Bus-free: the DEM engine links it.
#pragma once

#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "cosim/yaml_config.hpp"

namespace cosim {

// A file a run reads or writes, with the key or option that names it, for messages.
struct NamedFile {
  std::string what;  // e.g. "--output", "output.csv", "the config file", "tools[0].mesh"
  std::string path;  // as given (empty: none, skipped)
};

// True when a and b are the same file: the same inode when both exist (hard links, symlinks and
// "./x" vs "x" included), else the same canonical path.
bool same_file(const std::string& a, const std::string& b);

// Refuses, before anything is written, outputs that are the same file as each other or as an
// input, and outputs whose folder does not exist or that are folders. Raises
// config::ConfigError naming both paths (and the keys that give them) and the fix.
// require_folders = false skips the missing-folder check (dem_service at start-up: the master
// may still replace the output path; the check runs once the final paths are known).
void check_output_files(const std::vector<NamedFile>& outputs, const std::vector<NamedFile>& inputs,
                        bool require_folders = true);

// An output written under a temporary name beside its real one ("<folder>/.<name>.partial-<pid>")
// and renamed onto the real name by commit(): an existing file of that name is replaced only
// when the run has started writing it, and kept beside it (".<name>.previous-<pid>", a hard
// link: no copy, no space) until the new file is closed. Then done() drops the earlier file, or
// restore() (a write, flush or close failed) puts it back and removes the new one
// (docs/output.md#file-safety). Destroyed uncommitted, the temporary file is removed; destroyed
// committed without restore(), it does done(). A process that is killed leaves both.
class StagedFile {
 public:
  explicit StagedFile(std::string path);
  // A file continued in place (cosim_master --resume): a copy of it is kept as the earlier file
  // (".<name>.previous-<pid>") from now until done() or restore(); current() is the real name.
  // Raises std::runtime_error naming the file and the cause if the copy cannot be made.
  struct InPlace {};
  StagedFile(InPlace, std::string path);
  ~StagedFile();
  StagedFile(const StagedFile&) = delete;
  StagedFile& operator=(const StagedFile&) = delete;

  const std::string& path() const { return path_; }  // the real name
  // Where to write now: the temporary name before commit(), the real name after.
  const std::string& current() const { return committed_ ? path_ : temp_; }
  bool committed() const { return committed_; }
  // Renames the temporary file onto the real name (atomic within a folder); later calls do
  // nothing. Raises std::runtime_error naming both paths if the rename fails.
  void commit();
  // The new file is complete and closed: the earlier file of its name (if any) is removed.
  void done();
  // The new file could not be written: the earlier file goes back to the real name (or, if
  // there was none, the new one is removed). Returns what happened, as a sentence for the user.
  std::string restore();
  // The earlier file, while it is kept ("" if there was none, or it is resolved).
  const std::string& earlier() const { return earlier_; }

 private:
  std::string path_, temp_, earlier_;
  bool committed_ = false, resolved_ = false;
};

// A write to `path` failed: the message that names the file and the cause (the errno text,
// e.g. "No space left on device" or, past a file-size limit, "File too large").
inline std::string write_failure(const std::string& path, const std::string& cause) {
  const bool space = cause.find("No space") != std::string::npos ||
                     cause.find("too large") != std::string::npos ||
                     cause.find("quota") != std::string::npos;
  return "cannot write '" + path + "': " + (cause.empty() ? std::string("unknown cause") : cause) +
         (space ? " (free space on its disk, or write it to another one)" : "");
}

// Another live run writes the output (OutputLock).
struct OutputBusy : config::ConfigError {
  using config::ConfigError::ConfigError;
};

// One writer per output file (docs/output.md#one-writer-per-file). A lock file beside the output,
// "<folder>/.<name>.lock", holding the pid, host and program of its writer, locked (flock) for the
// life of this object; the kernel drops the lock when the process ends, however it ends.
class OutputLock {
 public:
  // Raises OutputBusy (a config::ConfigError) naming the output, the key that gives it and the
  // other run (program, pid, host, since when) if a live process holds the lock. A lock file
  // left by a process that ended without removing it (kill -9) is taken over: note() says whose.
  OutputLock(const NamedFile& output, const std::string& program);
  ~OutputLock();  // removes the lock file
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;
  const std::string& lock_path() const { return lock_path_; }
  const std::string& note() const { return note_; }  // "" unless a stale lock was taken over

 private:
  std::string lock_path_, note_;
  int fd_ = -1;
};

// Locks every named output (empty paths skipped) for `program`, printing each note on `notes`
// as "<program>: <note>". Raises OutputBusy as OutputLock does; locks taken so far are released.
std::vector<std::unique_ptr<OutputLock>> lock_outputs(const std::vector<NamedFile>& outputs,
                                                      const std::string& program,
                                                      std::ostream& notes);

}  // namespace cosim
