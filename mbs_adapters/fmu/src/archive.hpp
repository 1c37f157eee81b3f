// An FMU's zip archive unpacked into a private temporary folder that is removed again when the
// object goes (the process's normal exit, a signal handled by the participant, an exception).
#pragma once

#include <string>
#include <vector>

namespace fmu {

class UnpackedFmu {
 public:
  // Unpacks `path` (a .fmu zip). Raises FmuError naming the file for a missing or unreadable
  // file, one that is not a zip archive, a damaged archive and entries that would land outside
  // the folder ("../x", absolute names).
  explicit UnpackedFmu(const std::string& path);
  ~UnpackedFmu();
  UnpackedFmu(const UnpackedFmu&) = delete;
  UnpackedFmu& operator=(const UnpackedFmu&) = delete;

  const std::string& dir() const { return dir_; }      // the unpacked root
  const std::string& path() const { return path_; }    // the .fmu as given
  const std::vector<std::string>& entries() const { return entries_; }
  // The text of a file inside, "" with found=false when it is absent.
  std::string read(const std::string& relative, bool* found) const;

 private:
  std::string path_;
  std::string dir_;
  std::vector<std::string> entries_;
};

// The file URI of an absolute path (RFC 8089 "file:///..."), every byte outside RFC 3986's
// unreserved characters and '/' percent-encoded: "/tmp/a b%/" -> "file:///tmp/a%20b%25/".
std::string file_uri(const std::string& absolute_path);

// Removes a folder and everything below it; errors are ignored.
void remove_tree(const std::string& dir);

}  // namespace fmu
