#include "cosim/paths.hpp"

#include <filesystem>

namespace cosim {

std::string input_path(const std::string& config_dir, const std::string& path) {
  namespace fs = std::filesystem;
  if (path.empty() || config_dir.empty() || fs::path(path).is_absolute()) return path;
  const std::string beside = (fs::path(config_dir) / path).string();
  if (!fs::exists(beside) && fs::exists(path)) return path;
  return beside;
}

}  // namespace cosim
