// What the DEM records is checked, and what it allocates is checked first:
// * a fill too large for memory is refused before the particle arrays grow, naming the config
//   key and the bytes needed and available (docs/dem.md#memory), from /proc/meminfo and from an
//   address-space limit (RLIMIT_AS);
// * dem_run past a file-size limit (RLIMIT_FSIZE: a full disk to the writer) exits non-zero
//   naming its output and the cause, and an earlier output of that name stays as it was; a
//   finished output says complete = 1 (docs/dem.md#output);
// * a checkpoint that cannot be written leaves the earlier one whole.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cosim/h5.hpp"
#include "cosim/yaml_config.hpp"
#include "dem/bed.hpp"
#include "dem/checkpoint.hpp"
#include "dem/config.hpp"

namespace {

namespace fs = std::filesystem;

const char* kScene = R"(
scene: {dt: 1.0e-5, threads: 1}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact:
  particle_particle: {normal_stiffness: 4.0e7, restitution: 0.3, friction: 0.5}
walls:
  - {name: floor, type: plane, point: [0, 0, 0], normal: [0, 0, 1]}
particles:
  fill:
    - {species: grain, min: [0, 0, 0], max: [0.2, 0.2, 0.2], count: 200, seed: 3}
run: {duration: 0.02}
output: {particles_every: 0.001, wrenches_every: 1.0e-5}
)";

std::string dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path d = fs::temp_directory_path() /
                     ("dem_records_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d.string();
}

std::string refusal(const std::vector<std::string>& sets) {
  try {
    YAML::Node root = YAML::Load(kScene);
    for (const auto& s : sets) cosim::config::apply_override(root, s);
    dem::load_config(root, ".");
    return "";
  } catch (const cosim::config::ConfigError& e) {
    return e.what();
  }
}

std::string text_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Runs `cmd` (argv) with stdout and stderr to `log`, the file-size limit `fsize` (0: none) and
// SIGXFSZ ignored; returns its exit code.
int run(const std::vector<std::string>& cmd, const std::string& log, rlim_t fsize) {
  const pid_t pid = fork();
  if (pid == 0) {
    FILE* f = std::fopen(log.c_str(), "w");
    if (f) {
      dup2(fileno(f), 1);
      dup2(fileno(f), 2);
    }
    std::signal(SIGXFSZ, SIG_IGN);
    if (fsize > 0) {
      const rlimit limit{fsize, fsize};
      if (setrlimit(RLIMIT_FSIZE, &limit) != 0) _exit(126);
    }
    std::vector<char*> argv;
    for (const auto& a : cmd) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::int64_t complete_flag(const std::string& h5) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  cosim::h5::Handle f(H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!f.ok()) return -1;
  return cosim::h5::read_int_attribute(f, "complete");
}

}  // namespace

TEST(dem_Records, AFillTooLargeForMemoryIsRefusedNamingTheKeyAndTheBytes) {
  // 1e11 particles (70 TB) in a region that holds them: refused before anything is allocated.
  const std::string msg = refusal({"particles.fill.0.count=100000000000",
                                   "particles.fill.0.max=[100000, 100000, 100]"});
  EXPECT_NE(msg.find("particles.fill[0].count: a scene of 1e+11 particles needs at least 70000 GB"),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find("70000000000000 bytes"), std::string::npos) << msg;
  EXPECT_NE(msg.find("are available (MemAvailable in /proc/meminfo)"), std::string::npos) << msg;
  // A second fill adds to the first: the key named is the one that crosses the limit.
  const std::string second = refusal(
      {"particles.fill=[{species: grain, min: [0, 0, 0], max: [0.2, 0.2, 0.2], count: 200}, "
       "{species: grain, min: [0, 0, 0], max: [100000, 100000, 100], count: 100000000000}]"});
  EXPECT_NE(second.find("particles.fill[1].count: a scene of 1e+11 particles"), std::string::npos) << second;
  EXPECT_EQ(second.find("particles.fill[0]"), std::string::npos) << second;
  EXPECT_EQ(refusal({}), "") << "the small scene is accepted";
}

// Under an address-space limit (ulimit -v) the limit, not the machine's free memory, decides.
TEST(dem_Records, AnAddressSpaceLimitIsWhatIsAvailable) {
  int pipe_fd[2];
  ASSERT_EQ(pipe(pipe_fd), 0);
  const pid_t pid = fork();
  if (pid == 0) {
    close(pipe_fd[0]);
    // 300 MB more than the child has mapped now; a fill of 1e6 particles needs 700 MB.
    std::ifstream status("/proc/self/status");
    std::string key;
    double vm_kb = 0;
    while (status >> key)
      if (key == "VmSize:") status >> vm_kb;
    const rlim_t limit = static_cast<rlim_t>(vm_kb * 1024 + 300e6);
    const rlimit as{limit, limit};
    std::string msg = setrlimit(RLIMIT_AS, &as) == 0
                          ? refusal({"particles.fill.0.count=1000000", "particles.fill.0.max=[2, 2, 2]"})
                          : std::string("setrlimit failed");
    if (write(pipe_fd[1], msg.data(), msg.size()) < 0) _exit(2);
    _exit(0);
  }
  close(pipe_fd[1]);
  std::string msg;
  char buf[512];
  for (ssize_t n; (n = read(pipe_fd[0], buf, sizeof buf)) > 0;) msg.append(buf, static_cast<std::size_t>(n));
  close(pipe_fd[0]);
  waitpid(pid, nullptr, 0);
  EXPECT_NE(msg.find("particles.fill[0].count: a scene of 1e+06 particles needs at least 0.7 GB (700000000 bytes)"),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find("the address-space limit (RLIMIT_AS, ulimit -v)"), std::string::npos) << msg;
}

// dem_run's output past a file-size limit: a non-zero exit naming the file and the cause, the
// earlier output of that name as it was.
TEST(dem_Records, AFullDiskStopsDemRunAndKeepsTheEarlierOutput) {
  const std::string d = dir(), cfg = d + "/c.yaml", out = d + "/out.h5";
  std::ofstream(cfg) << kScene;
  const std::vector<std::string> cmd{DEM_RUN_EXE, cfg, "--output", out};
  ASSERT_EQ(run(cmd, d + "/first.log", 0), 0) << text_of(d + "/first.log");
  EXPECT_EQ(complete_flag(out), 1) << "a finished dem_run output says it is complete";
  const std::string earlier = text_of(out), earlier_xdmf = text_of(d + "/out.xdmf");
  ASSERT_GT(earlier.size(), 300000u);
  ASSERT_NE(earlier_xdmf.find("out.h5:/particles/"), std::string::npos) << earlier_xdmf;

  const int code = run(cmd, d + "/full.log", 200 * 1024);
  const std::string log = text_of(d + "/full.log");
  EXPECT_EQ(code, 1) << log;
  EXPECT_NE(log.find("cannot write '" + out + "'"), std::string::npos) << log;
  EXPECT_NE(log.find("File too large"), std::string::npos) << log;
  EXPECT_NE(log.find("the earlier '" + out + "' is back in place"), std::string::npos) << log;
  EXPECT_EQ(log.find("dem_run: wrote"), std::string::npos) << log;
  EXPECT_TRUE(text_of(out) == earlier) << "the earlier output was changed";
  EXPECT_TRUE(text_of(d + "/out.xdmf") == earlier_xdmf) << "the earlier XDMF was changed";
  for (const auto& e : fs::directory_iterator(d)) {
    EXPECT_EQ(e.path().filename().string().find(".partial-"), std::string::npos) << e.path();
    EXPECT_EQ(e.path().filename().string().find(".previous-"), std::string::npos) << e.path();
  }
}

// A checkpoint past the limit: the earlier checkpoint of that name stays whole and loads.
TEST(dem_Records, ACheckpointThatCannotBeWrittenLeavesTheEarlierOne) {
  const std::string d = dir(), ckpt = d + "/state.h5";
  YAML::Node root = YAML::Load(kScene);
  dem::RunConfig rc = dem::load_config(root, d);
  dem::save_checkpoint(rc.state, ckpt);
  const std::string earlier = text_of(ckpt);
  // Ten times the particles: a bigger checkpoint, written by a child under a 1.2x limit.
  cosim::config::apply_override(root, "particles.fill.0.count=2000");
  cosim::config::apply_override(root, "particles.fill.0.max=[0.5, 0.5, 0.5]");
  const dem::RunConfig big = dem::load_config(root, d);
  int pipe_fd[2];
  ASSERT_EQ(pipe(pipe_fd), 0);
  const pid_t pid = fork();
  if (pid == 0) {
    close(pipe_fd[0]);
    std::signal(SIGXFSZ, SIG_IGN);
    const rlim_t limit = static_cast<rlim_t>(earlier.size() * 6 / 5);
    const rlimit fs_limit{limit, limit};
    std::string msg = "saved";
    try {
      if (setrlimit(RLIMIT_FSIZE, &fs_limit) != 0) throw std::runtime_error("setrlimit failed");
      dem::save_checkpoint(big.state, ckpt);
    } catch (const std::exception& e) {
      msg = e.what();
    }
    if (write(pipe_fd[1], msg.data(), msg.size()) < 0) _exit(2);
    _exit(0);
  }
  close(pipe_fd[1]);
  std::string msg;
  char buf[512];
  for (ssize_t n; (n = read(pipe_fd[0], buf, sizeof buf)) > 0;) msg.append(buf, static_cast<std::size_t>(n));
  close(pipe_fd[0]);
  waitpid(pid, nullptr, 0);
  EXPECT_NE(msg.find("cannot write '" + ckpt + "'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("File too large"), std::string::npos) << msg;
  EXPECT_TRUE(text_of(ckpt) == earlier) << "the earlier checkpoint was changed";
  EXPECT_EQ(dem::load_checkpoint(ckpt).size(), rc.state.size());
  for (const auto& e : fs::directory_iterator(d))
    EXPECT_EQ(e.path().filename().string().find(".partial-"), std::string::npos) << e.path();
}
