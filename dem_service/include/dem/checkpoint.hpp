// HDF5 checkpoint of a State: everything the step reads, so a restored run continues bit for
// bit (with the same thread count). The scene is not stored: restore into the same scene.
#pragma once

#include <string>

#include "dem/state.hpp"

namespace dem {

// Throws std::runtime_error naming the file and the fix.
void save_checkpoint(const State& s, const std::string& path);
State load_checkpoint(const std::string& path);

}  // namespace dem
