// Helpers for the FMU importer's tests: zip archives read and written with minizip (to repack
// good FMUs into broken ones), the test-only failing FMU, the Reference FMUs' folder, CSVs.
#pragma once

#include <unzip.h>
#include <zip.h>

#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace fmutest {

using Entries = std::vector<std::pair<std::string, std::string>>;  // name, bytes ("" + '/' name: folder)

inline std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

inline Entries read_zip(const std::string& path) {
  Entries out;
  unzFile z = unzOpen64(path.c_str());
  if (!z) throw std::runtime_error("cannot open zip " + path);
  for (int rc = unzGoToFirstFile(z); rc == UNZ_OK; rc = unzGoToNextFile(z)) {
    unz_file_info64 info{};
    char name[4096];
    unzGetCurrentFileInfo64(z, &info, name, sizeof name, nullptr, 0, nullptr, 0);
    std::string data(info.uncompressed_size, '\0');
    if (unzOpenCurrentFile(z) == UNZ_OK) {
      if (!data.empty()) unzReadCurrentFile(z, data.data(), static_cast<unsigned>(data.size()));
      unzCloseCurrentFile(z);
    }
    out.emplace_back(name, data);
  }
  unzClose(z);
  return out;
}

inline void write_zip(const std::string& path, const Entries& entries) {
  zipFile z = zipOpen64(path.c_str(), APPEND_STATUS_CREATE);
  if (!z) throw std::runtime_error("cannot create zip " + path);
  for (const auto& [name, data] : entries) {
    zip_fileinfo info{};
    zipOpenNewFileInZip64(z, name.c_str(), &info, nullptr, 0, nullptr, 0, nullptr, Z_DEFLATED,
                          Z_DEFAULT_COMPRESSION, 1);
    if (!data.empty()) zipWriteInFileInZip(z, data.data(), static_cast<unsigned>(data.size()));
    zipCloseFileInZip(z);
  }
  zipClose(z, nullptr);
}

inline std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  for (auto at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size())) s.replace(at, from.size(), to);
  return s;
}

// The entry `name` of `entries` (throws when absent).
inline std::string& entry(Entries& entries, const std::string& name) {
  for (auto& [n, d] : entries)
    if (n == name) return d;
  throw std::runtime_error("no entry " + name);
}

inline std::string temp_path(const std::string& suffix) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = std::string(info->test_suite_name()) + "_" + info->name();
  for (auto& c : name)
    if (c == '/') c = '_';
  return std::string(TEST_TMP_DIR) + "/" + name + suffix;
}

// The test-only FMU (tests/fmu/fail_fmu), packed: good until its parameter fail_at.
inline Entries fail_fmu_entries() {
  return {{"modelDescription.xml", slurp(std::string(SOURCE_DIR) + "/tests/fmu/fail_fmu/modelDescription.xml")},
          {"binaries/", ""},
          {"binaries/linux64/", ""},
          {"binaries/linux64/fail_fmu.so", slurp(FAIL_FMU_SO)}};
}

// The test-only echo FMU (tests/fmu/echo_fmu): outputs copy the inputs, with FMU state support.
inline Entries echo_fmu_entries() {
  return {{"modelDescription.xml", slurp(std::string(SOURCE_DIR) + "/tests/fmu/echo_fmu/modelDescription.xml")},
          {"binaries/linux64/echo_fmu.so", slurp(ECHO_FMU_SO)}};
}

// The test-only counter FMU (tests/fmu/counter_fmu): ends itself at stop_at, reads its rate
// from resources/rate.txt, serializes its state.
inline Entries counter_fmu_entries(const std::string& rate = "2.5") {
  return {{"modelDescription.xml", slurp(std::string(SOURCE_DIR) + "/tests/fmu/counter_fmu/modelDescription.xml")},
          {"binaries/linux64/counter_fmu.so", slurp(COUNTER_FMU_SO)},
          {"resources/rate.txt", rate + "\n"}};
}

// The test-only FMI 3.0 FMU with arrays (tests/fmu/array_fmu3).
inline Entries array_fmu3_entries() {
  return {{"modelDescription.xml", slurp(std::string(SOURCE_DIR) + "/tests/fmu/array_fmu3/modelDescription.xml")},
          {"binaries/x86_64-linux/array_fmu3.so", slurp(ARRAY_FMU3_SO)}};
}

inline std::string pack(const Entries& e, const std::string& suffix = ".fmu") {
  const std::string path = temp_path(suffix);
  write_zip(path, e);
  return path;
}

inline std::string fmus_dir() { return std::string(FMUS_DIR) + "/fmi2"; }
inline bool have_fmus() { return std::filesystem::exists(fmus_dir() + "/BouncingBall.fmu"); }

// Skips the test (ctest reports it SKIPPED) when the Reference FMUs are not there: a clean clone
// in CI has no ../shared/fmus.
#define REQUIRE_REFERENCE_FMUS()                                                                  \
  do {                                                                                            \
    if (!fmutest::have_fmus())                                                                    \
      GTEST_SKIP() << "Reference FMUs not found in " << fmutest::fmus_dir()                        \
                   << " (set -DCOSIM_FMUS_DIR=<folder with fmi2/*.fmu>); this test needs them";   \
  } while (0)

inline std::string fmus3_dir() { return std::string(FMUS_DIR) + "/fmi3"; }
inline bool have_fmus3() { return std::filesystem::exists(fmus3_dir() + "/Dahlquist.fmu") && have_fmus(); }

// The FMI 3.0 Reference FMUs (compared against the CSVs in fmi2/, the same models).
#define REQUIRE_FMI3_REFERENCE_FMUS()                                                             \
  do {                                                                                            \
    if (!fmutest::have_fmus3())                                                                   \
      GTEST_SKIP() << "FMI 3.0 Reference FMUs not found in " << fmutest::fmus3_dir()               \
                   << " (or their CSVs in " << fmutest::fmus_dir() << "); this test needs them";  \
  } while (0)

struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  int column(const std::string& name) const {
    for (std::size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return static_cast<int>(i);
    throw std::runtime_error("no column " + name);
  }
  double number(std::size_t row, const std::string& name) const { return std::stod(rows[row][column(name)]); }
};

inline Table read_csv(const std::string& path) {
  Table t;
  std::ifstream in(path);
  std::string line;
  bool first = true;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::vector<std::string> cells;
    std::stringstream s(line);
    std::string cell;
    while (std::getline(s, cell, ',')) cells.push_back(cell);
    if (first) t.header = cells;
    else t.rows.push_back(cells);
    first = false;
  }
  return t;
}

}  // namespace fmutest
