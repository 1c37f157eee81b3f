// Two HDF5 records compared dataset by dataset, raw bytes in each dataset's own type, leaving
// out what differs between two runs of one config by nature: wall times (the master's per
// step, each participant's compute and round trip, the DEM's seconds_<section> diagnostics)
// and the bus counters.
#pragma once

#include <hdf5.h>

#include <algorithm>
#include <regex>
#include <string>
#include <vector>

namespace record_compare {

inline const std::regex& run_metadata() {
  static const std::regex re(
      R"(^(timing/(master|step_wall)|participants/[^/]+/timing/.*|participants/[^/]+/diagnostics/seconds_.*|bus/.*|participants/[^/]+/bus/.*|checkpoint/resumed_at)$)");
  return re;
}

inline std::vector<std::string> dataset_names(hid_t file) {
  std::vector<std::string> out;
  H5Ovisit(
      file, H5_INDEX_NAME, H5_ITER_INC,
      [](hid_t, const char* name, const H5O_info_t* info, void* data) -> herr_t {
        if (info->type == H5O_TYPE_DATASET) static_cast<std::vector<std::string>*>(data)->push_back(name);
        return 0;
      },
      &out);
  return out;
}

inline std::vector<char> raw(hid_t file, const std::string& name, std::vector<hsize_t>* dims) {
  const hid_t d = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  const hid_t type = H5Dget_type(d), space = H5Dget_space(d);
  dims->assign(static_cast<std::size_t>(std::max(0, H5Sget_simple_extent_ndims(space))), 0);
  if (!dims->empty()) H5Sget_simple_extent_dims(space, dims->data(), nullptr);
  std::vector<char> out(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)) * H5Tget_size(type));
  if (!out.empty()) H5Dread(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data());
  H5Sclose(space);
  H5Tclose(type);
  H5Dclose(d);
  return out;
}

struct Comparison {
  bool opened = false;
  std::vector<std::string> differ;   // in both, different
  std::vector<std::string> missing;  // in one only
  int compared = 0, skipped = 0;
  bool identical() const { return opened && differ.empty() && missing.empty(); }
  std::string text() const {
    std::string s;
    for (const auto& n : differ) s += " differs: " + n + "\n";
    for (const auto& n : missing) s += " in one only: " + n + "\n";
    return s;
  }
};

inline Comparison compare(const std::string& a, const std::string& b) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  Comparison c;
  const hid_t fa = H5Fopen(a.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t fb = H5Fopen(b.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (fa < 0 || fb < 0) {
    if (fa >= 0) H5Fclose(fa);
    if (fb >= 0) H5Fclose(fb);
    return c;
  }
  c.opened = true;
  const auto na = dataset_names(fa), nb = dataset_names(fb);
  for (const auto& n : na) {
    if (std::regex_match(n, run_metadata())) {
      ++c.skipped;
      continue;
    }
    if (std::find(nb.begin(), nb.end(), n) == nb.end()) {
      c.missing.push_back(n);
      continue;
    }
    std::vector<hsize_t> da, db;
    const auto ra = raw(fa, n, &da), rb = raw(fb, n, &db);
    ++c.compared;
    if (da != db || ra != rb) c.differ.push_back(n);
  }
  for (const auto& n : nb)
    if (!std::regex_match(n, run_metadata()) && std::find(na.begin(), na.end(), n) == na.end())
      c.missing.push_back(n);
  H5Fclose(fa);
  H5Fclose(fb);
  return c;
}

}  // namespace record_compare
