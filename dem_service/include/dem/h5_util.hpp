// The shared HDF5 helpers (protocol/support/include/cosim/h5.hpp) plus the DEM's Vec3 arrays, for
// checkpoints and run output.
#pragma once

#include "cosim/h5.hpp"
#include "dem/vec3.hpp"

namespace dem::h5 {

using cosim::h5::Handle;
using cosim::h5::read;
using cosim::h5::rows;
using cosim::h5::Table;
using cosim::h5::write;
using cosim::h5::write_double_attribute;
using cosim::h5::write_string_attribute;

inline void write(hid_t loc, const std::string& name, const std::vector<Vec3>& v) {
  write(loc, name, H5T_NATIVE_DOUBLE, v.data(), v.size(), 3);
}
inline std::vector<Vec3> read_vec3(hid_t loc, const std::string& name) {
  std::vector<Vec3> v(rows(loc, name));
  if (!v.empty()) read(loc, name, H5T_NATIVE_DOUBLE, v.data());
  return v;
}

}  // namespace dem::h5
