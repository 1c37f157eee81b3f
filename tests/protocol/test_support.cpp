// The bus-free helpers in protocol/: the timing table, input paths, the HDF5 table and the
// YAML motion reader (the trajectory's numerics are in tests/prescribed/test_trajectory.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cosim/files.hpp"
#include "cosim/h5.hpp"
#include "cosim/number_arg.hpp"
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

// --- Output files (cosim/files.hpp) and command-line numbers (cosim/number_arg.hpp). ---------

namespace {

fs::path fresh(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("support_files_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string refusal(const std::vector<cosim::NamedFile>& out, const std::vector<cosim::NamedFile>& in) {
  try {
    cosim::check_output_files(out, in);
    return "";
  } catch (const cosim::config::ConfigError& e) {
    return e.what();
  }
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

}  // namespace

TEST(Files, SameFileByInodeOrCanonicalPath) {
  const fs::path d = fresh("same");
  std::ofstream(d / "a.yaml") << "a: 1\n";
  fs::create_hard_link(d / "a.yaml", d / "hard.yaml");
  fs::create_symlink(d / "a.yaml", d / "soft.yaml");
  fs::create_directories(d / "sub");
  EXPECT_TRUE(cosim::same_file((d / "a.yaml").string(), (d / "hard.yaml").string()));
  EXPECT_TRUE(cosim::same_file((d / "a.yaml").string(), (d / "soft.yaml").string()));
  EXPECT_TRUE(cosim::same_file((d / "a.yaml").string(), (d / "sub/../a.yaml").string()));
  EXPECT_TRUE(cosim::same_file((d / "new.h5").string(), (d / "sub/../new.h5").string()));  // neither exists
  EXPECT_FALSE(cosim::same_file((d / "a.yaml").string(), (d / "new.h5").string()));
  EXPECT_FALSE(cosim::same_file((d / "x.h5").string(), (d / "y.h5").string()));
  EXPECT_FALSE(cosim::same_file("", ""));
}

TEST(Files, OutputsOntoEachOtherOrAnInputAreRefusedNamingBoth) {
  const fs::path d = fresh("check");
  std::ofstream(d / "run.yaml") << "a: 1\n";
  const std::string cfg = (d / "run.yaml").string(), h5 = (d / "x.h5").string();
  EXPECT_EQ(refusal({{"--output", h5}, {"--csv", (d / "x.csv").string()}}, {{"the config file", cfg}}), "");
  EXPECT_EQ(refusal({{"--output", h5}, {"--csv", h5}}, {}),
            "--output '" + h5 + "' and --csv '" + h5 +
                "' are the same file: both would write it and leave it unreadable; give them different names");
  EXPECT_EQ(refusal({{"--output", cfg}}, {{"the config file", cfg}}),
            "--output '" + cfg + "' is the same file as the config file '" + cfg +
                "', which this run reads: writing it would destroy the input; choose another output name");
  EXPECT_NE(refusal({{"--output", (d / "none" / "x.h5").string()}}, {}).find("the folder '" + (d / "none").string() + "' does not exist"),
            std::string::npos);
  EXPECT_NE(refusal({{"output.file", d.string()}}, {}).find("output.file '" + d.string() + "' is a folder"),
            std::string::npos);
  EXPECT_EQ(refusal({{"--output", ""}, {"--csv", ""}}, {{"the config file", cfg}}), "");  // none
}

TEST(Files, AStagedFileReplacesTheOldOneOnlyWhenCommitted) {
  const fs::path d = fresh("staged");
  const fs::path out = d / "out.h5";
  std::ofstream(out) << "old";
  {
    cosim::StagedFile f(out.string());
    EXPECT_NE(f.current(), out.string());
    EXPECT_EQ(fs::path(f.current()).parent_path(), d);  // same folder: the rename is atomic
    std::ofstream(f.current()) << "new";
    EXPECT_EQ(slurp(out), "old");
  }  // never committed: the temporary file goes, the old file stays
  EXPECT_EQ(slurp(out), "old");
  EXPECT_EQ(std::distance(fs::directory_iterator(d), fs::directory_iterator()), 1);
  {
    cosim::StagedFile f(out.string());
    std::ofstream(f.current()) << "new";
    f.commit();
    EXPECT_TRUE(f.committed());
    EXPECT_EQ(f.current(), out.string());
    f.commit();  // again: nothing
  }
  EXPECT_EQ(slurp(out), "new");
  EXPECT_EQ(std::distance(fs::directory_iterator(d), fs::directory_iterator()), 1);
}

TEST(NumberArg, NamesTheOptionAndWhatItExpects) {
  auto msg = [](auto f) {
    try {
      f();
      return std::string();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
  };
  EXPECT_EQ(cosim::parse_number_arg("--wait", "2.5", "seconds"), 2.5);
  EXPECT_EQ(cosim::parse_number_arg("--wait", "1e-3", "seconds"), 1e-3);
  EXPECT_EQ(msg([] { cosim::parse_number_arg("--wait", "soon", "seconds >= 0"); }),
            "--wait: 'soon' is not a number; expected seconds >= 0");
  for (const char* bad : {"", "5s", "nan", "inf", "1e999", "0x", "1,5"})
    EXPECT_NE(msg([&] { cosim::parse_number_arg("--x", bad, "a number"); }), "") << bad;
  EXPECT_EQ(msg([] { cosim::parse_number_arg("--element", "5", "0.02..1", 0.02, 1.0); }),
            "--element: 5 is out of range; expected 0.02..1");
  EXPECT_EQ(cosim::parse_integer_arg("--refine", "3", "1..4", 1, 4), 3);
  EXPECT_EQ(msg([] { cosim::parse_integer_arg("--refine", "2.5", "1..4", 1, 4); }),
            "--refine: '2.5' is not a whole number; expected 1..4");
  EXPECT_EQ(msg([] { cosim::parse_integer_arg("--refine", "0", "1..4", 1, 4); }),
            "--refine: 0 is out of range; expected 1..4");
}
