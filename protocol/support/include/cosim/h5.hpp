// Thin helpers over the HDF5 C API: fixed datasets and attributes, and the extendable table the
// master's recorder and the DEM's run output append rows to. Bus-free: the DEM engine links it.
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <string>
#include <vector>

namespace cosim::h5 {

// RAII closer for one hid_t.
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

// What HDF5's error stack says about the call that just failed: the system's reason where the
// file driver gives one ("No space left on device", "File too large" past a file-size limit),
// else the innermost message; "" when the stack is empty. Call it before any other HDF5 call.
std::string error_cause();
// "HDF5: cannot <what>: <cause>" as a std::runtime_error (the cause from error_cause()).
[[noreturn]] void fail(const std::string& what);

// Checked H5Fflush and H5Fclose of a file written to `path` (named in the message); they raise
// std::runtime_error "cannot write '<path>': <cause>" (cosim::write_failure). A file whose close
// failed stays open inside HDF5 until the process ends; this library turns off HDF5's own close
// at exit (H5dont_atexit), which crashes on such a file (HDF5 1.10).
void flush(hid_t file, const std::string& path);
void close(hid_t file, const std::string& path);
// An integer attribute, created or overwritten (the record's `complete` flag).
void set_int_attribute(hid_t loc, const std::string& name, std::int64_t value);
std::int64_t read_int_attribute(hid_t loc, const std::string& name);

// Writes rows x cols values as a 2-D dataset (1-D when cols == 0).
void write(hid_t loc, const std::string& name, hid_t type, const void* data, std::size_t rows,
           std::size_t cols);
template <class T>
void write(hid_t loc, const std::string& name, const std::vector<T>& v) {
  write(loc, name, type_of<T>(), v.data(), v.size(), 0);
}
// Number of rows of a dataset; throws std::runtime_error if it does not exist.
std::size_t rows(hid_t loc, const std::string& name);
void read(hid_t loc, const std::string& name, hid_t type, void* data);
template <class T>
std::vector<T> read(hid_t loc, const std::string& name) {
  std::vector<T> v(rows(loc, name));
  if (!v.empty()) read(loc, name, type_of<T>(), v.data());
  return v;
}

// Every value of a 1-D or 2-D dataset of numbers as doubles, row-major; *width (if given) gets
// the columns (1 for 1-D). Throws std::runtime_error naming the dataset.
std::vector<double> read_doubles(hid_t loc, const std::string& name, std::size_t* width = nullptr);
// A scalar string dataset or attribute of `loc`; throws std::runtime_error naming it.
std::string read_string(hid_t loc, const std::string& name);
std::string read_string_attribute(hid_t loc, const std::string& name);

// Scalar strings (fixed length, the string's own length) as an attribute or a dataset. Every
// writer raises std::runtime_error naming the dataset or attribute and the cause.
void write_string_attribute(hid_t loc, const std::string& name, const std::string& value);
void write_string(hid_t loc, const std::string& name, const std::string& value);
void write_double_attribute(hid_t loc, const std::string& name, double value);

// An extendable rows x width dataset of doubles (1-D when width is 1), created empty with any
// missing parent groups. Rows are buffered in memory and appended by flush(), so a run of many
// steps stays cheap; buffered rows can still be dropped (a repeated co-simulation step).
class Table {
 public:
  // Throws std::runtime_error naming the dataset if it cannot be created.
  Table(hid_t parent, const std::string& name, std::size_t width, std::size_t chunk_rows = 256);
  // Opens an existing table to append to, keeping its first `keep_rows` rows and dropping the
  // rest (a resumed run continues after its checkpoint). Throws std::runtime_error naming the
  // dataset if it is missing, not a table of doubles or shorter than keep_rows.
  struct Existing {};
  Table(Existing, hid_t parent, const std::string& name, std::size_t keep_rows);
  ~Table();  // closes the dataset; rows not flushed are dropped
  Table(const Table&) = delete;
  Table& operator=(const Table&) = delete;

  void attribute(const std::string& key, const std::string& value);
  void append(const double* row);               // width values
  void append(const std::vector<double>& row);  // a row of another width is stored as NaNs
  void append(double value) { append(std::vector<double>{value}); }  // NaNs unless width 1
  std::size_t width() const { return width_; }
  std::size_t buffered_rows() const { return buffer_.size() / width_; }
  void discard_rows_after(std::size_t keep);  // drops buffered rows after the first `keep`
  void flush();                               // throws std::runtime_error if it cannot write

 private:
  hid_t id_ = -1;
  std::string name_;
  std::size_t width_;
  hsize_t rows_ = 0;
  std::vector<double> buffer_;
};

}  // namespace cosim::h5
