// Where a file named in a config is looked for. Bus-free: the DEM engine links it.
#pragma once

#include <string>

namespace cosim {

// An input file (mesh, motion CSV, checkpoint to load) named in a config read from the folder
// `config_dir`: an absolute path, or an empty config_dir, as given; a relative path beside the
// config file, or in the working directory when it is only there. When neither exists the path
// beside the config is returned, so the reader's "not found" names where it looked first.
// Output files are not resolved: they are relative to the working directory.
std::string input_path(const std::string& config_dir, const std::string& path);

}  // namespace cosim
