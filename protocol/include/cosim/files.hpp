// Output files that never clobber anything by accident (docs/output.md#file-safety).
// Bus-free: the DEM engine links it.
#pragma once

#include <string>
#include <vector>

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
// when the run has started writing it. Destroyed uncommitted, the temporary file is removed.
class StagedFile {
 public:
  explicit StagedFile(std::string path);
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

 private:
  std::string path_, temp_;
  bool committed_ = false;
};

}  // namespace cosim
