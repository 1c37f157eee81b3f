// The bus-free helpers in protocol/: the timing table, input paths, the HDF5 table and the
// YAML motion reader (the trajectory's numerics are in tests/prescribed/test_trajectory.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cosim/h5.hpp"
#include "cosim/paths.hpp"
#include "cosim/timer.hpp"
#include "cosim/trajectory.hpp"
#include "cosim/yaml_config.hpp"

namespace fs = std::filesystem;

TEST(Timer, SectionsAccumulateAndPrintAsOneTable) {
  cosim::Timer t({"broad_phase", "output"});
  t.add(0, 1.5);
  const cosim::Timer before = t;
  t.add(0, 0.5);
  t.add(1, 2.0);
  EXPECT_DOUBLE_EQ(t.sum(), 4.0);
  const auto since = t.rows_since(before);
  ASSERT_EQ(since.size(), 2u);
  EXPECT_EQ(since[0].section, "broad_phase");
  EXPECT_DOUBLE_EQ(since[0].seconds, 0.5);
  EXPECT_DOUBLE_EQ(since[1].seconds, 2.0);
  cosim::Stopwatch w;
  t.lap(1, w);
  EXPECT_GE(t.seconds(1), 2.0);

  std::ostringstream out;
  cosim::print_timing_table(out, "Loop time of 8 s", {{"broad_phase", 2.0}, {"other", 6.0}}, 8.0,
                            {"a note"});
  EXPECT_EQ(out.str(),
            "\nLoop time of 8 s\n\n"
            "Section               |   time (s) |  %total\n"
            "----------------------+------------+--------\n"
            "broad_phase           |      2.000 |  25.00\n"
            "other                 |      6.000 |  75.00\n"
            "\na note\n");
  t.reset();
  EXPECT_EQ(t.sum(), 0.0);
}

TEST(InputPath, BesideTheConfigFirstThenTheWorkingDirectory) {
  const fs::path dir = fs::temp_directory_path() / "cosim_input_path_test";
  fs::create_directories(dir);
  std::ofstream(dir / "beside.csv") << "x\n";
  const fs::path cwd_file = fs::current_path() / "cosim_input_path_only_here.csv";
  std::ofstream(cwd_file) << "x\n";
  EXPECT_EQ(cosim::input_path(dir.string(), "beside.csv"), (dir / "beside.csv").string());
  EXPECT_EQ(cosim::input_path(dir.string(), "cosim_input_path_only_here.csv"),
            "cosim_input_path_only_here.csv");
  // Nowhere: the path beside the config, so the "not found" names where it looked first.
  EXPECT_EQ(cosim::input_path(dir.string(), "missing.csv"), (dir / "missing.csv").string());
  EXPECT_EQ(cosim::input_path(dir.string(), "/abs/file.csv"), "/abs/file.csv");
  EXPECT_EQ(cosim::input_path("", "rel.csv"), "rel.csv");
  fs::remove(cwd_file);
}

TEST(H5Table, AppendsBufferedRowsDropsDiscardedOnesAndPadsBadRowsWithNaN) {
  const std::string path = (fs::temp_directory_path() / "cosim_h5_table_test.h5").string();
  {
    cosim::h5::Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT),
                           H5Fclose);
    cosim::h5::Table wide(file, "group/wide", 2, 4);
    cosim::h5::Table narrow(file, "narrow", 1);
    const double r0[2] = {1, 2}, r1[2] = {3, 4};
    wide.append(r0);
    wide.flush();
    wide.append(r1);
    wide.append(std::vector<double>{9});  // wrong width
    EXPECT_EQ(wide.buffered_rows(), 2u);
    wide.discard_rows_after(1);
    wide.append(std::vector<double>{5});  // NaN row
    wide.flush();
    narrow.append(7.0);
    narrow.flush();
  }
  cosim::h5::Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  EXPECT_EQ(cosim::h5::rows(file, "group/wide"), 3u);
  std::vector<double> v(6);
  cosim::h5::read(file, "group/wide", H5T_NATIVE_DOUBLE, v.data());
  EXPECT_EQ(v[0], 1);
  EXPECT_EQ(v[3], 4);
  EXPECT_TRUE(std::isnan(v[4]) && std::isnan(v[5]));
  EXPECT_EQ(cosim::h5::read<double>(file, "narrow"), std::vector<double>{7});
  EXPECT_THROW(cosim::h5::rows(file, "absent"), std::runtime_error);
}

TEST(ReadTrajectory, OneOfKeyframesOrCsvWithTheKeyNamedInTheCallersStyle) {
  const auto motion = [](const std::string& yaml, const std::string& path) {
    return cosim::read_trajectory(YAML::Load(yaml), path, "");
  };
  const auto tr = motion("{interpolation: cubic, keyframes: [{time: 0, position: [0, 0, 0]}, "
                         "{time: 1, position: [1, 0, 0], orientation: [2, 0, 0, 0]}]}",
                         "tools.0");
  EXPECT_EQ(tr.interpolation, cosim::Trajectory::Interpolation::cubic);
  EXPECT_EQ(tr.keyframes[1].orientation, (cosim::Quat{1, 0, 0, 0}));  // normalised
  const auto refused = [&](const std::string& yaml, const std::string& path,
                           const std::string& expected) {
    try {
      motion(yaml, path);
      ADD_FAILURE() << yaml;
    } catch (const cosim::config::ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  };
  refused("{interpolation: linear}", "tools.0", "tools.0: give exactly one of keyframes or csv");
  refused("{keyframes: [{time: 0, position: [0, 0]}]}", "tools.0", "tools.0.keyframes.0.position");
  refused("{keyframes: [{time: 0, position: [0, 0]}]}", "tools[0].motion",
          "tools[0].motion.keyframes[0].position");
  refused("{keyframes: [{time: 1, position: [0, 0, 0]}, {time: 1, position: [0, 0, 0]}]}",
          "tools.0", "increase strictly");
  refused("{csv: /nonexistent/motion.csv}", "tools.0", "tools.0.csv: motion file");
}
