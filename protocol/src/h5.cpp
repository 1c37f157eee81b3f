#include "cosim/h5.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace cosim::h5 {
namespace {

// A fixed-length C string type as long as the value (at least 1).
hid_t string_type(const std::string& value) {
  const hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, std::max<std::size_t>(1, value.size()));
  return type;
}

}  // namespace

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

std::vector<double> read_doubles(hid_t loc, const std::string& name, std::size_t* width) {
  if (H5Lexists(loc, name.c_str(), H5P_DEFAULT) <= 0)
    throw std::runtime_error("dataset '" + name + "' missing");
  Handle set(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), H5Dclose);
  Handle space(H5Dget_space(set), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space);
  if (rank < 1 || rank > 2) throw std::runtime_error("dataset '" + name + "' is not a table");
  hsize_t dims[2] = {0, 1};
  H5Sget_simple_extent_dims(space, dims, nullptr);
  if (width) *width = rank == 1 ? 1 : dims[1];
  std::vector<double> v(static_cast<std::size_t>(dims[0] * (rank == 1 ? 1 : dims[1])));
  if (!v.empty() && H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0)
    throw std::runtime_error("cannot read dataset '" + name + "'");
  return v;
}

namespace {
std::string read_fixed_string(hid_t id, hid_t type_of_it, bool attribute, const std::string& name) {
  if (H5Tget_class(type_of_it) != H5T_STRING || H5Tis_variable_str(type_of_it) > 0)
    throw std::runtime_error("'" + name + "' is not a fixed-length string");
  std::string out(H5Tget_size(type_of_it), '\0');
  Handle memory(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(memory, out.size());
  const herr_t e = attribute ? H5Aread(id, memory, out.data())
                             : H5Dread(id, memory, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data());
  if (e < 0) throw std::runtime_error("cannot read '" + name + "'");
  if (const auto end = out.find('\0'); end != std::string::npos) out.resize(end);
  return out;
}
}  // namespace

std::string read_string(hid_t loc, const std::string& name) {
  if (H5Lexists(loc, name.c_str(), H5P_DEFAULT) <= 0)
    throw std::runtime_error("dataset '" + name + "' missing");
  Handle set(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), H5Dclose);
  Handle type(H5Dget_type(set), H5Tclose);
  return read_fixed_string(set, type, false, name);
}

std::string read_string_attribute(hid_t loc, const std::string& name) {
  if (H5Aexists(loc, name.c_str()) <= 0) throw std::runtime_error("attribute '" + name + "' missing");
  Handle attr(H5Aopen(loc, name.c_str(), H5P_DEFAULT), H5Aclose);
  Handle type(H5Aget_type(attr), H5Tclose);
  return read_fixed_string(attr, type, true, name);
}

void write_string_attribute(hid_t loc, const std::string& name, const std::string& value) {
  Handle type(string_type(value), H5Tclose);
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle attr(H5Acreate2(loc, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  H5Awrite(attr, type, value.c_str());
}

void write_string(hid_t loc, const std::string& name, const std::string& value) {
  Handle type(string_type(value), H5Tclose);
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle set(H5Dcreate2(loc, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
             H5Dclose);
  if (!set.ok()) throw std::runtime_error("HDF5: cannot create dataset '" + name + "'");
  H5Dwrite(set, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, value.c_str());
}

void write_double_attribute(hid_t loc, const std::string& name, double value) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle attr(H5Acreate2(loc, name.c_str(), H5T_NATIVE_DOUBLE, space, H5P_DEFAULT, H5P_DEFAULT),
              H5Aclose);
  H5Awrite(attr, H5T_NATIVE_DOUBLE, &value);
}

Table::Table(hid_t parent, const std::string& name, std::size_t width, std::size_t chunk_rows)
    : name_(name), width_(width) {
  const int rank = width == 1 ? 1 : 2;
  const hsize_t dims[2] = {0, width}, maxdims[2] = {H5S_UNLIMITED, width};
  const hsize_t chunk[2] = {chunk_rows, width};
  Handle space(H5Screate_simple(rank, dims, maxdims), H5Sclose);
  Handle props(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  H5Pset_chunk(props, rank, chunk);
  Handle links(H5Pcreate(H5P_LINK_CREATE), H5Pclose);
  H5Pset_create_intermediate_group(links, 1);
  id_ = H5Dcreate2(parent, name.c_str(), H5T_NATIVE_DOUBLE, space, links, props, H5P_DEFAULT);
  if (id_ < 0) throw std::runtime_error("HDF5: cannot create dataset '" + name + "'");
}

Table::Table(Existing, hid_t parent, const std::string& name, std::size_t keep_rows) : name_(name) {
  if (H5Lexists(parent, name.c_str(), H5P_DEFAULT) <= 0)
    throw std::runtime_error("dataset '" + name + "' is missing");
  id_ = H5Dopen2(parent, name.c_str(), H5P_DEFAULT);
  if (id_ < 0) throw std::runtime_error("HDF5: cannot open dataset '" + name + "'");
  Handle space(H5Dget_space(id_), H5Sclose);
  Handle type(H5Dget_type(id_), H5Tclose);
  const int rank = H5Sget_simple_extent_ndims(space);
  hsize_t dims[2] = {0, 1};
  if (rank < 1 || rank > 2 || H5Tget_class(type) != H5T_FLOAT)
    throw std::runtime_error("dataset '" + name + "' is not a table of numbers");
  H5Sget_simple_extent_dims(space, dims, nullptr);
  width_ = rank == 1 ? 1 : dims[1];
  if (dims[0] < keep_rows)
    throw std::runtime_error("dataset '" + name + "' has " + std::to_string(dims[0]) +
                             " rows, fewer than the " + std::to_string(keep_rows) + " to keep");
  const hsize_t size[2] = {keep_rows, width_};
  if (dims[0] > keep_rows && H5Dset_extent(id_, size) < 0)
    throw std::runtime_error("HDF5: cannot shorten dataset '" + name + "'");
  rows_ = keep_rows;
}

Table::~Table() {
  if (id_ >= 0) H5Dclose(id_);
}

void Table::attribute(const std::string& key, const std::string& value) {
  write_string_attribute(id_, key, value);
}

void Table::append(const double* row) { buffer_.insert(buffer_.end(), row, row + width_); }

void Table::append(const std::vector<double>& row) {
  if (row.size() == width_) append(row.data());
  else buffer_.insert(buffer_.end(), width_, std::numeric_limits<double>::quiet_NaN());
}

void Table::discard_rows_after(std::size_t keep) {
  if (keep < buffered_rows()) buffer_.resize(keep * width_);
}

void Table::flush() {
  const hsize_t n = buffered_rows();
  if (n == 0) return;
  const int rank = width_ == 1 ? 1 : 2;
  const hsize_t size[2] = {rows_ + n, width_};
  const hsize_t start[2] = {rows_, 0}, count[2] = {n, width_};
  H5Dset_extent(id_, size);
  Handle file_space(H5Dget_space(id_), H5Sclose);
  H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, count, nullptr);
  Handle memory(H5Screate_simple(rank, count, nullptr), H5Sclose);
  if (H5Dwrite(id_, H5T_NATIVE_DOUBLE, memory, file_space, H5P_DEFAULT, buffer_.data()) < 0)
    throw std::runtime_error("HDF5: cannot append to '" + name_ + "'");
  rows_ += n;
  buffer_.clear();
}

}  // namespace cosim::h5
