#include "dem/h5_util.hpp"

#include <stdexcept>

namespace dem::h5 {

void write(hid_t loc, const std::string& name, hid_t type, const void* data, std::size_t rows,
           std::size_t cols) {
  const hsize_t dims[2] = {rows, cols};
  Handle space(H5Screate_simple(cols ? 2 : 1, dims, nullptr), H5Sclose);
  Handle set(H5Dcreate2(loc, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
             H5Dclose);
  if (!set.ok()) throw std::runtime_error("HDF5: cannot create dataset '" + name + "'");
  if (rows > 0 && H5Dwrite(set, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
    throw std::runtime_error("HDF5: cannot write dataset '" + name + "'");
}

std::size_t rows(hid_t loc, const std::string& name) {
  if (H5Lexists(loc, name.c_str(), H5P_DEFAULT) <= 0)
    throw std::runtime_error("dataset '" + name + "' missing");
  Handle set(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), H5Dclose);
  Handle space(H5Dget_space(set), H5Sclose);
  hsize_t dims[2] = {0, 0};
  H5Sget_simple_extent_dims(space, dims, nullptr);
  return dims[0];
}

void read(hid_t loc, const std::string& name, hid_t type, void* data) {
  Handle set(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), H5Dclose);
  if (!set.ok() || H5Dread(set, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
    throw std::runtime_error("cannot read dataset '" + name + "'");
}

void write_string_attribute(hid_t loc, const std::string& name, const std::string& value) {
  Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(type, value.size() + 1);
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle attr(H5Acreate2(loc, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  H5Awrite(attr, type, value.c_str());
}

void write_double_attribute(hid_t loc, const std::string& name, double value) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle attr(H5Acreate2(loc, name.c_str(), H5T_NATIVE_DOUBLE, space, H5P_DEFAULT, H5P_DEFAULT),
              H5Aclose);
  H5Awrite(attr, H5T_NATIVE_DOUBLE, &value);
}

void create_series(hid_t loc, const std::string& name, std::size_t cols) {
  const hsize_t dims[2] = {0, cols}, maxdims[2] = {H5S_UNLIMITED, cols};
  const hsize_t chunk[2] = {1024, cols};
  Handle space(H5Screate_simple(2, dims, maxdims), H5Sclose);
  Handle plist(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  H5Pset_chunk(plist, 2, chunk);
  Handle set(H5Dcreate2(loc, name.c_str(), H5T_NATIVE_DOUBLE, space, H5P_DEFAULT, plist,
                        H5P_DEFAULT),
             H5Dclose);
  if (!set.ok()) throw std::runtime_error("HDF5: cannot create series '" + name + "'");
}

void append_series(hid_t loc, const std::string& name, const double* data, std::size_t n,
                   std::size_t cols) {
  if (n == 0) return;
  Handle set(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), H5Dclose);
  hsize_t dims[2];
  {
    Handle space(H5Dget_space(set), H5Sclose);
    H5Sget_simple_extent_dims(space, dims, nullptr);
  }
  const hsize_t start[2] = {dims[0], 0}, count[2] = {n, cols};
  const hsize_t new_dims[2] = {dims[0] + n, cols};
  H5Dset_extent(set, new_dims);
  Handle file_space(H5Dget_space(set), H5Sclose);
  H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, count, nullptr);
  Handle mem_space(H5Screate_simple(2, count, nullptr), H5Sclose);
  if (H5Dwrite(set, H5T_NATIVE_DOUBLE, mem_space, file_space, H5P_DEFAULT, data) < 0)
    throw std::runtime_error("HDF5: cannot append to '" + name + "'");
}

}  // namespace dem::h5
