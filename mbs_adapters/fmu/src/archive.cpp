#include "archive.hpp"

#include <sys/stat.h>
#include <unistd.h>
#include <unzip.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "model_description.hpp"

namespace fmu {

namespace fs = std::filesystem;

void remove_tree(const std::string& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  fs::remove_all(dir, ec);
}

std::string file_uri(const std::string& path) {
  static const char* hex = "0123456789ABCDEF";
  std::string out = "file://";
  for (const unsigned char c : path) {
    const bool unreserved = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                            c == '-' || c == '.' || c == '_' || c == '~' || c == '/';
    if (unreserved) {
      out += static_cast<char>(c);
    } else {
      out += '%';
      out += hex[c >> 4];
      out += hex[c & 15];
    }
  }
  return out;
}

namespace {

// A zip entry name that stays inside the folder: relative, no "..", no backslashes.
bool safe_name(const std::string& name) {
  if (name.empty() || name[0] == '/' || name.find('\\') != std::string::npos) return false;
  std::stringstream s(name);
  std::string part;
  while (std::getline(s, part, '/'))
    if (part == "..") return false;
  return true;
}

struct ZipCloser {
  unzFile z;
  ~ZipCloser() {
    if (z) unzClose(z);
  }
};

// Folders of adapters that were killed (SIGKILL leaves no chance to clean up): fmu_adapter_<pid>_*
// whose process is gone.
void remove_stale_folders(const std::string& base) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(base, ec)) {
    const std::string name = e.path().filename().string();
    const std::string prefix = "fmu_adapter_";
    if (name.rfind(prefix, 0) != 0 || !e.is_directory(ec)) continue;
    const auto end = name.find('_', prefix.size());
    if (end == std::string::npos) continue;
    const std::string pid = name.substr(prefix.size(), end - prefix.size());
    if (pid.empty() || pid.find_first_not_of("0123456789") != std::string::npos) continue;
    struct stat st {};
    if (stat(e.path().c_str(), &st) != 0 || st.st_uid != getuid()) continue;
    if (!fs::exists("/proc/" + pid, ec)) remove_tree(e.path().string());
  }
}

}  // namespace

UnpackedFmu::UnpackedFmu(const std::string& path) : path_(path) {
  const std::string what = "FMU '" + path + "'";
  std::error_code ec;
  if (!fs::exists(path, ec))
    throw FmuError(what + ": file not found (check the path: relative paths are looked up beside the config file, then in the working directory)");
  if (fs::is_directory(path, ec))
    throw FmuError(what + ": is a folder, not an .fmu file (an FMU is one zip archive)");
  {
    std::ifstream probe(path, std::ios::binary);
    if (!probe) throw FmuError(what + ": cannot be read (" + std::strerror(errno) + ")");
    char magic[4] = {0, 0, 0, 0};
    probe.read(magic, 4);
    if (probe.gcount() < 4 || magic[0] != 'P' || magic[1] != 'K')
      throw FmuError(what + ": not a zip archive (an FMU is a zip file with modelDescription.xml and binaries/); "
                     "the file is damaged or not an FMU");
  }
  ZipCloser zip{unzOpen64(path.c_str())};
  if (!zip.z)
    throw FmuError(what + ": not a readable zip archive (damaged or truncated); export the FMU again");

  const char* tmp = std::getenv("TMPDIR");
  std::string base = (tmp && *tmp) ? tmp : "/tmp";
  remove_stale_folders(base);
  std::string templ = base + "/fmu_adapter_" + std::to_string(getpid()) + "_XXXXXX";
  std::vector<char> buf(templ.begin(), templ.end());
  buf.push_back('\0');
  if (!mkdtemp(buf.data()))
    throw FmuError(what + ": cannot create a temporary folder under " + base + " (" + std::strerror(errno) + ")");
  dir_ = buf.data();

  try {
    int rc = unzGoToFirstFile(zip.z);
    if (rc != UNZ_OK) throw FmuError(what + ": the zip archive has no entries or is damaged");
    std::vector<char> data(1 << 16);
    while (rc == UNZ_OK) {
      unz_file_info64 info{};
      char name_buf[4096];
      if (unzGetCurrentFileInfo64(zip.z, &info, name_buf, sizeof name_buf, nullptr, 0, nullptr, 0) != UNZ_OK)
        throw FmuError(what + ": damaged zip directory");
      const std::string name = name_buf;
      if (!safe_name(name))
        throw FmuError(what + ": the archive holds an entry named '" + name +
                       "' that would land outside its folder; refused");
      const fs::path out = fs::path(dir_) / name;
      if (!name.empty() && name.back() == '/') {
        fs::create_directories(out, ec);
      } else {
        fs::create_directories(out.parent_path(), ec);
        if (unzOpenCurrentFile(zip.z) != UNZ_OK)
          throw FmuError(what + ": cannot read entry '" + name + "' (damaged archive)");
        std::ofstream f(out, std::ios::binary);
        if (!f) {
          unzCloseCurrentFile(zip.z);
          throw FmuError(what + ": cannot write '" + out.string() + "' while unpacking");
        }
        int n = 0;
        while ((n = unzReadCurrentFile(zip.z, data.data(), static_cast<unsigned>(data.size()))) > 0)
          f.write(data.data(), n);
        const int closed = unzCloseCurrentFile(zip.z);  // checks the CRC
        if (n < 0 || closed != UNZ_OK)
          throw FmuError(what + ": entry '" + name + "' is damaged (zip error " +
                         std::to_string(n < 0 ? n : closed) + "); export the FMU again");
        entries_.push_back(name);
      }
      rc = unzGoToNextFile(zip.z);
    }
    if (rc != UNZ_END_OF_LIST_OF_FILE) throw FmuError(what + ": damaged zip directory");
  } catch (...) {
    remove_tree(dir_);
    dir_.clear();
    throw;
  }
}

UnpackedFmu::~UnpackedFmu() { remove_tree(dir_); }

std::string UnpackedFmu::read(const std::string& relative, bool* found) const {
  std::ifstream in(fs::path(dir_) / relative, std::ios::binary);
  *found = static_cast<bool>(in);
  if (!in) return "";
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace fmu
