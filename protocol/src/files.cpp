#include "cosim/files.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
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

StagedFile::StagedFile(std::string path) : path_(std::move(path)) {
  const fs::path p(path_);
  temp_ = (p.parent_path() / ("." + p.filename().string() + ".partial-" +
                              std::to_string(static_cast<long>(::getpid()))))
              .string();
}

StagedFile::~StagedFile() {
  if (!committed_) std::remove(temp_.c_str());
}

void StagedFile::commit() {
  if (committed_) return;
  if (std::rename(temp_.c_str(), path_.c_str()) != 0)
    throw std::runtime_error("cannot rename '" + temp_ + "' to '" + path_ +
                             "': " + std::strerror(errno) +
                             " (is the folder writable, or is the output a folder?)");
  committed_ = true;
}

}  // namespace cosim
