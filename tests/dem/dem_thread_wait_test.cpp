// scene.thread_wait: the key is validated, the plan keeps what the user set, and dem_run really
// runs with the OpenMP wait settings the policy asks for (libgomp prints the settings it loaded
// with when OMP_DISPLAY_ENV is set; dem_run re-executes itself to change them).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "cosim/yaml_config.hpp"
#include "dem/config.hpp"
#include "dem/thread_wait.hpp"

namespace {

namespace fs = std::filesystem;
using dem::ThreadWait;
using Action = dem::ThreadWaitPlan::Action;

const char* kConfig = R"(
scene: {dt: 1.0e-5, threads: 2, min_particles_per_thread: 1}
materials: {sand: {density: 2600}}
species: [{name: grain, material: sand, radius: 0.005}]
contact:
  particle_particle: {normal_stiffness: 4.0e7, restitution: 0.3}
particles:
  list:
    - {species: grain, position: [0, 0, 0.1]}
    - {species: grain, position: [0.02, 0, 0.1]}
run: {duration: 1.0e-4}
output: {progress_every: 100}
)";

std::string error_of(const std::string& set) {
  try {
    YAML::Node root = YAML::Load(kConfig);
    cosim::config::apply_override(root, set);
    dem::read_thread_wait(root);
    dem::load_config(root, ".");
    return "";
  } catch (const std::exception& e) {
    return e.what();
  }
}

TEST(dem_ThreadWait, ConfigKeyIsReadAndValidated) {
  YAML::Node root = YAML::Load(kConfig);
  EXPECT_EQ(dem::read_thread_wait(root), dem::Scene{}.thread_wait);
  for (ThreadWait w : {ThreadWait::passive, ThreadWait::brief, ThreadWait::spin}) {
    cosim::config::apply_override(root, std::string("scene.thread_wait=") + dem::thread_wait_name(w));
    EXPECT_EQ(dem::read_thread_wait(root), w);
    EXPECT_EQ(dem::load_config(root, ".").scene.thread_wait, w);
  }
  const std::string msg = error_of("scene.thread_wait=sometimes");
  for (const char* part : {"scene.thread_wait", "sometimes", "passive", "brief", "spin"})
    EXPECT_NE(msg.find(part), std::string::npos) << "message '" << msg << "' lacks '" << part << "'";
  EXPECT_NE(error_of("scene.thread_wait=[passive]"), "");
}

TEST(dem_ThreadWait, PlanSetsTheVariablesOfThePolicyOnce) {
  auto p = dem::plan_thread_wait(ThreadWait::passive, nullptr, nullptr, nullptr);
  EXPECT_EQ(p.action, Action::reexec);
  const std::vector<std::pair<std::string, std::string>> passive{
      {"OMP_WAIT_POLICY", "PASSIVE"}, {dem::kThreadWaitGuard, "passive"}};
  EXPECT_EQ(p.set, passive);
  p = dem::plan_thread_wait(ThreadWait::brief, nullptr, nullptr, nullptr);
  EXPECT_EQ(p.action, Action::reexec);
  const std::vector<std::pair<std::string, std::string>> brief{
      {"GOMP_SPINCOUNT", std::to_string(dem::kBriefSpinCount)}, {dem::kThreadWaitGuard, "brief"}};
  EXPECT_EQ(p.set, brief);
  // libgomp's default is the spin policy: nothing to do without a variable set.
  EXPECT_EQ(dem::plan_thread_wait(ThreadWait::spin, nullptr, nullptr, nullptr).action, Action::none);
  // After the re-execution the guard names the policy: done (no loop).
  EXPECT_EQ(dem::plan_thread_wait(ThreadWait::passive, "PASSIVE", nullptr, "passive").action,
            Action::none);
  EXPECT_EQ(dem::plan_thread_wait(ThreadWait::brief, nullptr, "10000", "brief").action, Action::none);
  // Variables that came with a guard for another policy are ours: replaced, not kept.
  p = dem::plan_thread_wait(ThreadWait::spin, "PASSIVE", nullptr, "passive");
  EXPECT_EQ(p.action, Action::reexec);
  EXPECT_EQ(p.set, (std::vector<std::pair<std::string, std::string>>{{dem::kThreadWaitGuard, "spin"}}));
  EXPECT_EQ(p.unset, (std::vector<std::string>{"OMP_WAIT_POLICY", "GOMP_SPINCOUNT"}));
}

TEST(dem_ThreadWait, TheUsersEnvironmentWins) {
  for (ThreadWait w : {ThreadWait::passive, ThreadWait::brief, ThreadWait::spin}) {
    auto p = dem::plan_thread_wait(w, "ACTIVE", nullptr, nullptr);
    EXPECT_EQ(p.action, Action::user_environment);
    EXPECT_NE(p.note.find("OMP_WAIT_POLICY=ACTIVE"), std::string::npos) << p.note;
    p = dem::plan_thread_wait(w, nullptr, "123", nullptr);
    EXPECT_EQ(p.action, Action::user_environment);
    EXPECT_NE(p.note.find("GOMP_SPINCOUNT=123"), std::string::npos) << p.note;
    EXPECT_TRUE(p.set.empty());
  }
}

// Runs dem_run on kConfig with `env` prepended and OMP_DISPLAY_ENV=verbose; returns its output.
std::string run_dem_run(const std::string& env, const std::string& thread_wait) {
  const fs::path d = fs::temp_directory_path() / ("dem_thread_wait_" + std::to_string(::getpid()));
  fs::create_directories(d);
  std::ofstream(d / "c.yaml") << kConfig;
  const std::string log = (d / "log.txt").string();
  const std::string cmd = "env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT -u " +
                          std::string(dem::kThreadWaitGuard) + " " + env +
                          " OMP_DISPLAY_ENV=verbose " + DEM_RUN_EXE + " " + (d / "c.yaml").string() +
                          " --set scene.thread_wait=" + thread_wait + " --output " +
                          (d / "out.h5").string() + " > " + log + " 2>&1";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The spin count of the last settings block libgomp printed (the process that ran).
std::string last_spincount(const std::string& out) {
  const std::regex re(R"(GOMP_SPINCOUNT = '([^']*)')");
  std::string last;
  for (auto it = std::sregex_iterator(out.begin(), out.end(), re); it != std::sregex_iterator(); ++it)
    last = (*it)[1];
  return last;
}

TEST(dem_ThreadWait, DemRunRunsWithThePolicysSettings) {
  std::string out = run_dem_run("", "passive");
  EXPECT_EQ(last_spincount(out), "0") << out;
  EXPECT_NE(out.find("idle threads wait passive"), std::string::npos) << out;
  out = run_dem_run("", "brief");
  EXPECT_EQ(last_spincount(out), std::to_string(dem::kBriefSpinCount)) << out;
  out = run_dem_run("", "spin");
  EXPECT_EQ(last_spincount(out), "300000") << out;
  // The user's variable is kept whatever the config says.
  out = run_dem_run("GOMP_SPINCOUNT=777", "passive");
  EXPECT_EQ(last_spincount(out), "777") << out;
  EXPECT_NE(out.find("as the environment says"), std::string::npos) << out;
  // dem_run re-executed once, not in a loop: libgomp printed its settings twice at most.
  out = run_dem_run("", "passive");
  const std::regex begin("OPENMP DISPLAY ENVIRONMENT BEGIN");
  EXPECT_EQ(std::distance(std::sregex_iterator(out.begin(), out.end(), begin), std::sregex_iterator()), 2)
      << out;
  fs::remove_all(fs::temp_directory_path() / ("dem_thread_wait_" + std::to_string(::getpid())));
}

}  // namespace
