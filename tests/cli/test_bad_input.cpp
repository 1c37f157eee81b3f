// Bad input to every program, as a user would give it: each case runs the program and checks
// its exit code and that its message names the file, option or key (docs/testing.md lists the
// cases). Outputs that would clobber an input or each other are refused before anything is
// written, and a refused or failed start leaves an existing output file as it was.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <ostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace fs = std::filesystem;

std::string read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void write(const fs::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

// A folder of its own per test, holding the files the cases name.
fs::path work() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = std::string(info->test_suite_name()) + "_" + info->name();
  for (char& c : name)
    if (c == '/') c = '_';
  const fs::path d = fs::path(TEST_TMP_DIR) / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// A UDP port of its own per test (the cases that reach the bus).
std::string bus_url() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string name = std::string(info->test_suite_name()) + "." + info->name();
  const unsigned port = 40000 + static_cast<unsigned>(std::hash<std::string>{}(name) % 20000);
  return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0";
}

struct Result {
  int code = -1;  // exit code, 128 + signal, -1 on timeout
  std::string log;
};

// Runs the program (argv[0] a name in the build's bin folder) in `dir`, stdout and stderr to a log.
Result run(const fs::path& dir, std::vector<std::string> args, double timeout_s = 60) {
  args[0] = std::string(BIN_DIR) + "/" + args[0];
  const fs::path log = dir / "run.log";
  const pid_t pid = fork();
  if (pid == 0) {
    if (chdir(dir.c_str()) != 0) _exit(126);
    FILE* f = std::fopen(log.c_str(), "w");
    if (f) {
      dup2(fileno(f), 1);
      dup2(fileno(f), 2);
    }
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  Result r;
  const auto start = std::chrono::steady_clock::now();
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() < timeout_s) {
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) {
      r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      r.log = read(log);
      return r;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
  r.log = read(log);
  return r;
}

const char* kAsciiSquare =
    "solid square\n"
    " facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 0.1 0 0\n   vertex 0 0.1 0\n"
    "  endloop\n endfacet\n"
    " facet normal 0 0 1\n  outer loop\n   vertex 0.1 0 0\n   vertex 0.1 0.1 0\n   vertex 0 0.1 0\n"
    "  endloop\n endfacet\n"
    "endsolid square\n";

// A DEM scene small enough to run in well under a second.
const char* kDem = R"(scene: {dt: 1.0e-5, threads: 1}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact:
  particle_particle: {normal_stiffness: 4.0e7, restitution: 0.3, friction: 0.5}
tools: [{name: plate, mesh: plate.stl}]
particles:
  list:
    - {species: grain, position: [0, 0, 0.1]}
run: {duration: 1.0e-4}
output: {file: dem.h5}
)";

// The files every case may name, in a fresh folder.
fs::path files() {
  const fs::path d = work();
  fs::create_directories(d / "a_folder");
  write(d / "scalar.yaml", "just a value\n");
  write(d / "duplicate.yaml", "time: {end: 1}\nscheme: jacobi\ntime: {end: 2}\n");
  write(d / "plate.stl", kAsciiSquare);
  write(d / "dem.yaml", kDem);
  write(d / "existing.h5", "an existing output that a refused run must leave alone\n");
  fs::copy_file(fs::path(SOURCE_DIR) / "configs/oscillator.yaml", d / "oscillator.yaml");
  fs::copy_file(fs::path(SOURCE_DIR) / "configs/hauler/machine.yaml", d / "machine.yaml");
  return d;
}

struct Case {
  const char* name;
  std::vector<std::string> args;  // argv
  int code;
  std::string message;  // a substring of the program's output
  // Extra set-up in the case's folder (files to corrupt, configs to change).
  std::function<void(const fs::path&)> setup = nullptr;
};

// gtest prints a parameter it cannot print as its raw bytes in ctest's test names; the case's
// program and arguments say more.
void PrintTo(const Case& c, std::ostream* os) {
  for (std::size_t i = 0; i < c.args.size(); ++i) *os << (i ? " " : "") << c.args[i];
}

class BadInput : public ::testing::TestWithParam<Case> {};

TEST_P(BadInput, IsRefusedWithAMessageNamingIt) {
  const Case& c = GetParam();
  const fs::path d = files();
  if (c.setup) c.setup(d);
  // Every file of the folder as it was before the run: a refusal writes nothing.
  std::map<std::string, std::string> before;
  for (const auto& e : fs::recursive_directory_iterator(d))
    if (e.is_regular_file()) before[e.path().string()] = read(e.path());
  const Result r = run(d, c.args);
  EXPECT_EQ(r.code, c.code) << r.log;
  EXPECT_NE(r.log.find(c.message), std::string::npos) << "expected '" << c.message << "' in:\n" << r.log;
  EXPECT_EQ(r.log.find("terminate called"), std::string::npos) << r.log;
  for (const auto& [path, text] : before) {
    if (fs::path(path).filename() == "run.log") continue;
    EXPECT_EQ(read(path), text) << path << " was changed by a refused run";
  }
  for (const auto& e : fs::recursive_directory_iterator(d)) {
    if (e.is_regular_file() && fs::path(e.path()).filename() != "run.log") {
      EXPECT_TRUE(before.count(e.path().string())) << e.path() << " was written by a refused run";
    }
  }
}

void set_dem(const fs::path& d, const std::string& from, const std::string& to) {
  std::string t = read(d / "dem.yaml");
  const auto at = t.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  t.replace(at, from.size(), to);
  write(d / "dem.yaml", t);
}

std::vector<std::string> master(std::vector<std::string> extra) {
  std::vector<std::string> a{"cosim_master", "oscillator.yaml", "--set", "output.progress=off"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

INSTANTIATE_TEST_SUITE_P(
    Programs, BadInput,
    ::testing::Values(
        // A config path that is a folder, a config that is one YAML value, a duplicate key.
        Case{"master_config_is_a_folder", {"cosim_master", "a_folder"}, 2, "config file 'a_folder' is a folder, not a file"},
        Case{"master_config_is_a_scalar", {"cosim_master", "scalar.yaml"}, 2,
             "scalar.yaml: expected a map of 'key: value' lines at the top level, got the single value 'just a value'"},
        Case{"master_duplicate_key", {"cosim_master", "duplicate.yaml"}, 2,
             "duplicate.yaml:3:1: duplicate key 'time' (first at line 1)"},
        Case{"dem_run_config_is_a_folder", {"dem_run", "a_folder"}, 2, "config file 'a_folder' is a folder"},
        Case{"dem_run_config_is_a_scalar", {"dem_run", "scalar.yaml"}, 2, "got the single value 'just a value'"},
        Case{"dem_service_config_is_a_folder", {"dem_service", "a_folder"}, 2, "config file 'a_folder' is a folder"},
        Case{"dem_service_config_is_a_scalar", {"dem_service", "scalar.yaml"}, 2, "got the single value 'just a value'"},
        Case{"hauler_config_is_a_folder", {"hauler_adapter", "a_folder"}, 2, "config file 'a_folder' is a folder"},
        Case{"wheel_loader_config_is_a_scalar", {"wheel_loader_adapter", "scalar.yaml"}, 2, "got the single value"},
        Case{"prescribed_config_is_a_folder", {"prescribed_adapter", "a_folder"}, 2, "is a folder"},
        Case{"prescribed_config_is_a_scalar", {"prescribed_adapter", "scalar.yaml"}, 2, "got the single value"},
        Case{"hauler_duplicate_key", {"hauler_adapter", "dup_machine.yaml"}, 2, "duplicate key 'gravity' (first at line 13)",
             [](const fs::path& d) { write(d / "dup_machine.yaml", read(d / "machine.yaml") + "gravity: 1.62\n"); }},
        Case{"body_mesh_config_is_a_folder", {"body_mesh", "--output", "body.stl", "--config", "a_folder"}, 2, "is a folder"},
        // Outputs onto each other or onto an input.
        Case{"master_output_equals_csv", master({"--output", "x.h5", "--csv", "x.h5"}), 2,
             "--output 'x.h5' and --csv 'x.h5' are the same file"},
        Case{"master_output_onto_its_config", master({"--output", "oscillator.yaml"}), 2,
             "--output 'oscillator.yaml' is the same file as the config file 'oscillator.yaml'"},
        Case{"master_output_onto_its_config_by_another_name", master({"--output", "a_folder/../oscillator.yaml"}), 2,
             "is the same file as the config file"},
        Case{"master_csv_onto_a_hard_link_of_the_config", master({"--output", "x.h5", "--csv", "link.yaml"}), 2,
             "--csv 'link.yaml' is the same file as the config file",
             [](const fs::path& d) { fs::create_hard_link(d / "oscillator.yaml", d / "link.yaml"); }},
        Case{"master_bad_csv_folder_keeps_the_hdf5", master({"--output", "existing.h5", "--csv", "no_such_folder/x.csv"}), 2,
             "--csv 'no_such_folder/x.csv': the folder 'no_such_folder' does not exist"},
        Case{"master_output_is_a_folder", master({"--output", "a_folder"}), 2, "--output 'a_folder' is a folder"},
        Case{"dem_run_output_onto_its_config", {"dem_run", "dem.yaml", "--output", "dem.yaml"}, 2,
             "--output 'dem.yaml' is the same file as the config file 'dem.yaml'"},
        Case{"dem_run_output_onto_its_mesh", {"dem_run", "dem.yaml", "--output", "plate.stl"}, 2,
             "is the same file as tools[0].mesh"},
        Case{"dem_run_checkpoint_onto_the_output", {"dem_run", "dem.yaml"}, 2,
             "output.file 'dem.h5' and output.checkpoint 'dem.h5' are the same file",
             [](const fs::path& d) { set_dem(d, "output: {file: dem.h5}", "output: {file: dem.h5, checkpoint: dem.h5}"); }},
        Case{"dem_run_checkpoint_onto_its_input_checkpoint", {"dem_run", "dem.yaml"}, 2,
             "output.checkpoint 'existing.h5' is the same file as particles.checkpoint",
             [](const fs::path& d) {
               // the checkpoint is read before the outputs are checked: make it a real one
               fs::remove(d / "existing.h5");
               const Result prep = run(d, {"dem_run", "dem.yaml", "--set", "output.checkpoint=existing.h5",
                                           "--output", "prep.h5"});
               ASSERT_EQ(prep.code, 0) << prep.log;
               set_dem(d, "output: {file: dem.h5}", "output: {file: dem.h5, checkpoint: existing.h5}");
               set_dem(d, "particles:\n  list:", "particles:\n  checkpoint: existing.h5\n  list:");
               set_dem(d, "position: [0, 0, 0.1]", "position: [0.5, 0, 0.1]");
             }},
        Case{"dem_service_output_onto_its_config", {"dem_service", "dem.yaml", "--set", "output.file=dem.yaml"}, 2,
             "output.file 'dem.yaml' is the same file as the config file 'dem.yaml'"},
        Case{"body_mesh_output_onto_its_config", {"body_mesh", "--output", "machine.yaml", "--config", "machine.yaml"}, 2,
             "--output 'machine.yaml' is the same file as --config 'machine.yaml'"},
        // Meshes and particles.
        Case{"truncated_ascii_stl", {"dem_run", "dem.yaml"}, 2, "the ASCII STL ends at line",
             [](const fs::path& d) { std::string s = kAsciiSquare; write(d / "plate.stl", s.substr(0, s.size() / 2)); }},
        Case{"nan_vertex", {"dem_run", "dem.yaml"}, 2, "vertex 4 (triangle 1, corner 1) y is 'nan': not a finite number",
             [](const fs::path& d) {
               std::string s = kAsciiSquare;
               s.replace(s.find("vertex 0.1 0.1 0"), 16, "vertex 0.1 nan 0");
               write(d / "plate.stl", s);
             }},
        Case{"huge_vertex", {"dem_run", "dem.yaml"}, 2, "vertex 1 (triangle 0, corner 1) x is 1e300, beyond the 32-bit floats",
             [](const fs::path& d) {
               std::string s = kAsciiSquare;
               s.replace(s.find("vertex 0.1 0 0"), 14, "vertex 1e300 0 0");
               write(d / "plate.stl", s);
             }},
        Case{"empty_particle_set", {"dem_run", "dem.yaml", "--set", "particles.list=[]"}, 2,
             "particles: the scene has no particles (particles.list is empty)"},
        // Numbers on command lines.
        Case{"participant_wait_soon", {"oscillator_adapter", "--side", "mass1", "--wait", "soon"}, 2,
             "--wait: 'soon' is not a number; expected seconds >= 0"},
        Case{"participant_idle_timeout_trailing", {"oscillator_adapter", "--side", "mass1", "--idle-timeout", "5s"}, 2,
             "--idle-timeout: '5s' is not a number; expected seconds > 0"},
        Case{"participant_idle_timeout_negative", {"oscillator_adapter", "--side", "mass1", "--idle-timeout", "-1"}, 2,
             "--idle-timeout must be > 0"},
        Case{"dem_service_wait_nan", {"dem_service", "dem.yaml", "--wait", "nan"}, 2, "--wait: 'nan' is not a number"},
        Case{"hauler_wait_word", {"hauler_adapter", "--wait", "later"}, 2, "--wait: 'later' is not a number"},
        Case{"bucket_mesh_refine_word", {"bucket_mesh", "--output", "b.stl", "--refine", "fine"}, 2,
             "--refine: 'fine' is not a whole number; expected a whole number 1..4"},
        Case{"bucket_mesh_refine_range", {"bucket_mesh", "--output", "b.stl", "--refine", "9"}, 2,
             "--refine: 9 is out of range; expected a whole number 1..4"},
        Case{"bucket_mesh_width_inf", {"bucket_mesh", "--output", "b.stl", "--width", "inf"}, 2,
             "--width: 'inf' is not a number"},
        Case{"body_mesh_element_range", {"body_mesh", "--output", "b.stl", "--element", "5"}, 2,
             "--element: 5 is out of range; expected an edge length in m, 0.02..1"},
        Case{"stability_h_word", {"cosim_stability", "--H", "soon"}, 2, "--H: 'soon' is not a number"},
        Case{"stability_order_range", {"cosim_stability", "--kq", "7"}, 2, "--kq: '7' is not allowed"}),
    [](const auto& info) { return std::string(info.param.name); });

// A start that fails after the checks (a participant that exits at once) says that no step was
// recorded, not that its steps are in a file it never wrote, and leaves an existing file alone.
TEST(FailedStart, SaysNothingWasRecordedAndKeepsTheExistingOutput) {
  const fs::path d = files();
  const std::string old = read(d / "existing.h5");
  const Result r = run(d, master({"--output", "existing.h5", "--csv", "existing.csv", "--set",
                                  "bus.url=" + bus_url(), "--set", "participants.mass1.launch=[/bin/false]"}));
  EXPECT_EQ(r.code, 1) << r.log;
  EXPECT_EQ(r.log.find("the steps completed so far are in"), std::string::npos) << r.log;
  EXPECT_NE(r.log.find("no step was recorded; existing.h5 was not written"), std::string::npos) << r.log;
  EXPECT_EQ(read(d / "existing.h5"), old);
  EXPECT_FALSE(fs::exists(d / "existing.csv"));
  for (const auto& e : fs::directory_iterator(d))
    EXPECT_EQ(e.path().filename().string().find(".partial-"), std::string::npos) << e.path() << " left behind";
}

// A run that starts replaces the existing file (via its temporary name) and leaves no
// temporary file behind.
TEST(FinishedRun, ReplacesTheExistingOutputAndLeavesNoTemporaryFile) {
  const fs::path d = files();
  const Result r = run(d, master({"--output", "existing.h5", "--csv", "run.csv", "--set", "bus.url=" + bus_url(),
                                  "--set", "time.end=0.01", "--set", "time.macro_step=1e-3"}));
  ASSERT_EQ(r.code, 0) << r.log;
  EXPECT_EQ(read(d / "existing.h5").rfind("\x89HDF", 0), 0u) << "not an HDF5 file";
  EXPECT_EQ(read(d / "run.csv").rfind("time,", 0), 0u);
  for (const auto& e : fs::directory_iterator(d))
    EXPECT_EQ(e.path().filename().string().find(".partial-"), std::string::npos) << e.path() << " left behind";
  const Result dem = run(d, {"dem_run", "dem.yaml", "--output", "existing.h5"});
  ASSERT_EQ(dem.code, 0) << dem.log;
  EXPECT_EQ(read(d / "existing.h5").rfind("\x89HDF", 0), 0u);
  EXPECT_TRUE(fs::exists(d / "existing.xdmf"));
  for (const auto& e : fs::directory_iterator(d))
    EXPECT_EQ(e.path().filename().string().find(".partial-"), std::string::npos) << e.path() << " left behind";
}

}  // namespace
