#include "cosim/h5.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>

#include "cosim/files.hpp"

namespace cosim::h5 {
namespace {

// A fixed-length C string type as long as the value (at least 1).
hid_t string_type(const std::string& value) {
  const hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, std::max<std::size_t>(1, value.size()));
  return type;
}

// HDF5 closes the files still open at exit from an atexit handler; a file whose flush failed
// (a full disk) makes that handler crash (HDF5 1.10.8: SIGSEGV after the failed H5Fclose).
// Every file here is closed by its owner, so the handler has nothing to do: it is turned off
// before the library starts (the call must come before any other HDF5 call of the process).
const bool kNoCloseAtExit = H5dont_atexit() >= 0;

herr_t collect(unsigned, const H5E_error2_t* e, void* data) {
  auto& out = *static_cast<std::vector<std::string>*>(data);
  if (e->desc) out.emplace_back(e->desc);
  return 0;
}

}  // namespace

std::string error_cause() {
  (void)kNoCloseAtExit;
  std::vector<std::string> messages;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, collect, &messages);
  // The file driver's message carries the system's: "..., errno = 28, error message = 'No
  // space left on device', ...".
  for (auto it = messages.rbegin(); it != messages.rend(); ++it) {
    const std::string key = "error message = '";
    const auto at = it->find(key);
    if (at == std::string::npos) continue;
    const auto end = it->find('\'', at + key.size());
    if (end != std::string::npos) return it->substr(at + key.size(), end - at - key.size());
  }
  return messages.empty() ? std::string() : messages.back();
}

void fail(const std::string& what) {
  const std::string cause = error_cause();
  throw std::runtime_error("HDF5: cannot " + what + (cause.empty() ? "" : ": " + cause));
}

void flush(hid_t file, const std::string& path) {
  if (H5Fflush(file, H5F_SCOPE_GLOBAL) < 0)
    throw std::runtime_error(cosim::write_failure(path, error_cause()));
}

void close(hid_t file, const std::string& path) {
  if (H5Fclose(file) < 0) throw std::runtime_error(cosim::write_failure(path, error_cause()));
}

void set_int_attribute(hid_t loc, const std::string& name, std::int64_t value) {
  if (H5Aexists(loc, name.c_str()) > 0) {
    Handle attr(H5Aopen(loc, name.c_str(), H5P_DEFAULT), H5Aclose);
    if (!attr.ok() || H5Awrite(attr, H5T_NATIVE_INT64, &value) < 0) fail("write attribute '" + name + "'");
    return;
  }
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle attr(H5Acreate2(loc, name.c_str(), H5T_NATIVE_INT64, space, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!attr.ok() || H5Awrite(attr, H5T_NATIVE_INT64, &value) < 0) fail("write attribute '" + name + "'");
}

std::int64_t read_int_attribute(hid_t loc, const std::string& name) {
  if (H5Aexists(loc, name.c_str()) <= 0) throw std::runtime_error("attribute '" + name + "' missing");
  Handle attr(H5Aopen(loc, name.c_str(), H5P_DEFAULT), H5Aclose);
  std::int64_t v = 0;
  if (!attr.ok() || H5Aread(attr, H5T_NATIVE_INT64, &v) < 0)
    throw std::runtime_error("cannot read attribute '" + name + "'");
  return v;
}

void write(hid_t loc, const std::string& name, hid_t type, const void* data, std::size_t rows,
           std::size_t cols) {
  const hsize_t dims[2] = {rows, cols};
  Handle space(H5Screate_simple(cols ? 2 : 1, dims, nullptr), H5Sclose);
  Handle set(H5Dcreate2(loc, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
             H5Dclose);
  if (!set.ok()) fail("create dataset '" + name + "'");
  if (rows > 0 && H5Dwrite(set, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
    fail("write dataset '" + name + "'");
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
  if (!attr.ok() || H5Awrite(attr, type, value.c_str()) < 0) fail("write attribute '" + name + "'");
}

void write_string(hid_t loc, const std::string& name, const std::string& value) {
  Handle type(string_type(value), H5Tclose);
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle set(H5Dcreate2(loc, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
             H5Dclose);
  if (!set.ok()) fail("create dataset '" + name + "'");
  if (H5Dwrite(set, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, value.c_str()) < 0)
    fail("write dataset '" + name + "'");
}

void write_double_attribute(hid_t loc, const std::string& name, double value) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle attr(H5Acreate2(loc, name.c_str(), H5T_NATIVE_DOUBLE, space, H5P_DEFAULT, H5P_DEFAULT),
              H5Aclose);
  if (!attr.ok() || H5Awrite(attr, H5T_NATIVE_DOUBLE, &value) < 0) fail("write attribute '" + name + "'");
}

Table::Table(hid_t parent, const std::string& name, std::size_t width, std::size_t chunk_rows)
    : name_(name), width_(width) {
  const int rank = width == 1 ? 1 : 2;
  const hsize_t dims[2] = {0, width}, maxdims[2] = {H5S_UNLIMITED, width};
  const hsize_t chunk[2] = {chunk_rows, width};
  Handle space(H5Screate_simple(rank, dims, maxdims), H5Sclose);
  Handle props(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (H5Pset_chunk(props, rank, chunk) < 0) fail("set the chunks of '" + name + "'");
  Handle links(H5Pcreate(H5P_LINK_CREATE), H5Pclose);
  H5Pset_create_intermediate_group(links, 1);
  id_ = H5Dcreate2(parent, name.c_str(), H5T_NATIVE_DOUBLE, space, links, props, H5P_DEFAULT);
  if (id_ < 0) fail("create dataset '" + name + "'");
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
  if (H5Dset_extent(id_, size) < 0) fail("extend '" + name_ + "'");
  Handle file_space(H5Dget_space(id_), H5Sclose);
  if (!file_space.ok() ||
      H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, count, nullptr) < 0)
    fail("select rows of '" + name_ + "'");
  Handle memory(H5Screate_simple(rank, count, nullptr), H5Sclose);
  if (H5Dwrite(id_, H5T_NATIVE_DOUBLE, memory, file_space, H5P_DEFAULT, buffer_.data()) < 0)
    fail("append to '" + name_ + "'");
  rows_ += n;
  buffer_.clear();
}

}  // namespace cosim::h5
