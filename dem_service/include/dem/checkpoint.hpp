// HDF5 checkpoint of a State: everything the step reads, so a restored run continues bit for
// bit (with the same thread count). The scene is not stored: restore into the same scene.
#pragma once

#include <string>

#include "dem/state.hpp"

namespace dem {

// Written under a temporary name and renamed onto `path` once closed, so a failed write (a full
// disk) leaves an earlier checkpoint of that name whole. Every write and the close are checked:
// throws std::runtime_error naming the file and the cause, or the fix.
void save_checkpoint(const State& s, const std::string& path);
State load_checkpoint(const std::string& path);

}  // namespace dem
