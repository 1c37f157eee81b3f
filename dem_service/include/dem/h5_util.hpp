// Thin helpers over the HDF5 C API shared by checkpoints and run output.
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <string>
#include <vector>

#include "dem/vec3.hpp"

namespace dem::h5 {

// RAII handle closer for one hid_t.
class Handle {
 public:
  Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() {
    if (id_ >= 0) close_(id_);
  }
  operator hid_t() const { return id_; }
  bool ok() const { return id_ >= 0; }

 private:
  hid_t id_;
  herr_t (*close_)(hid_t);
};

template <class T>
hid_t type_of();
template <>
inline hid_t type_of<double>() { return H5T_NATIVE_DOUBLE; }
template <>
inline hid_t type_of<std::int32_t>() { return H5T_NATIVE_INT32; }
template <>
inline hid_t type_of<std::int64_t>() { return H5T_NATIVE_INT64; }
template <>
inline hid_t type_of<std::uint64_t>() { return H5T_NATIVE_UINT64; }
template <>
inline hid_t type_of<std::uint8_t>() { return H5T_NATIVE_UINT8; }
template <>
inline hid_t type_of<std::uint32_t>() { return H5T_NATIVE_UINT32; }

// Writes rows x cols values as a 2-D dataset (1-D when cols == 0).
void write(hid_t loc, const std::string& name, hid_t type, const void* data, std::size_t rows,
           std::size_t cols);
template <class T>
void write(hid_t loc, const std::string& name, const std::vector<T>& v) {
  write(loc, name, type_of<T>(), v.data(), v.size(), 0);
}
inline void write(hid_t loc, const std::string& name, const std::vector<Vec3>& v) {
  write(loc, name, H5T_NATIVE_DOUBLE, v.data(), v.size(), 3);
}
// Number of rows of a dataset; throws if it does not exist.
std::size_t rows(hid_t loc, const std::string& name);
void read(hid_t loc, const std::string& name, hid_t type, void* data);
template <class T>
std::vector<T> read(hid_t loc, const std::string& name) {
  std::vector<T> v(rows(loc, name));
  if (!v.empty()) read(loc, name, type_of<T>(), v.data());
  return v;
}
inline std::vector<Vec3> read_vec3(hid_t loc, const std::string& name) {
  std::vector<Vec3> v(rows(loc, name));
  if (!v.empty()) read(loc, name, H5T_NATIVE_DOUBLE, v.data());
  return v;
}
void write_string_attribute(hid_t loc, const std::string& name, const std::string& value);
void write_double_attribute(hid_t loc, const std::string& name, double value);

// An extendable rows x cols double dataset that grows by appending rows.
void create_series(hid_t loc, const std::string& name, std::size_t cols);
void append_series(hid_t loc, const std::string& name, const double* data, std::size_t rows,
                   std::size_t cols);

}  // namespace dem::h5
