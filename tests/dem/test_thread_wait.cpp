// scene.thread_wait: the key is validated, the plan keeps what the user set, and dem_run really
// runs with the OpenMP wait settings the policy asks for (libgomp prints the settings it loaded
// with when OMP_DISPLAY_ENV is set; dem_run re-executes itself to change them).
#include <gtest/gtest.h>
#include <sched.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "cosim/yaml_config.hpp"
#include "dem/config.hpp"
#include "dem/thread_wait.hpp"

namespace {

namespace fs = std::filesystem;
using dem::ThreadWait;
using Action = dem::ThreadWaitPlan::Action;

const char* kConfig = R"(
scene: {dt: 1.0e-5, threads: 2}
performance: {min_particles_per_thread: 1}
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
  for (ThreadWait w : {ThreadWait::passive, ThreadWait::brief, ThreadWait::spin, ThreadWait::yield}) {
    cosim::config::apply_override(root, std::string("scene.thread_wait=") + dem::thread_wait_name(w));
    EXPECT_EQ(dem::read_thread_wait(root), w);
    EXPECT_EQ(dem::load_config(root, ".").scene.thread_wait, w);
  }
  const std::string msg = error_of("scene.thread_wait=sometimes");
  for (const char* part : {"scene.thread_wait", "sometimes", "passive", "brief", "spin", "yield"})
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
  // yield: the step's own threads yield; OpenMP's other regions wait passively.
  p = dem::plan_thread_wait(ThreadWait::yield, nullptr, nullptr, nullptr);
  EXPECT_EQ(p.action, Action::reexec);
  const std::vector<std::pair<std::string, std::string>> yield{
      {"OMP_WAIT_POLICY", "PASSIVE"}, {dem::kThreadWaitGuard, "yield"}};
  EXPECT_EQ(p.set, yield);
  EXPECT_EQ(dem::plan_thread_wait(ThreadWait::yield, "PASSIVE", nullptr, "yield").action, Action::none);
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
  for (ThreadWait w : {ThreadWait::passive, ThreadWait::brief, ThreadWait::spin, ThreadWait::yield}) {
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
  out = run_dem_run("", "yield");
  EXPECT_EQ(last_spincount(out), "0") << out;
  EXPECT_NE(out.find("idle threads wait yield"), std::string::npos) << out;
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

// The CPUs each OpenMP thread may run on, and the one it ran on, from dem_run's start-up line
// "dem_run: thread 0 on CPUs 0-1 (running on 1); thread 1 on CPUs 0-1 (running on 0)".
struct SeenThread {
  std::set<int> allowed;
  int now = -1;
};
std::vector<SeenThread> seen_threads(const std::string& out) {
  std::vector<SeenThread> seen;
  const std::regex re(R"(thread (\d+) on CPUs ([0-9,\-]+) \(running on (-?\d+)\))");
  for (auto it = std::sregex_iterator(out.begin(), out.end(), re); it != std::sregex_iterator(); ++it) {
    SeenThread t;
    std::stringstream list((*it)[2].str());
    std::string part;
    while (std::getline(list, part, ',')) {
      const std::size_t dash = part.find('-');
      const int a = std::stoi(part.substr(0, dash));
      const int b = dash == std::string::npos ? a : std::stoi(part.substr(dash + 1));
      for (int c = a; c <= b; ++c) t.allowed.insert(c);
    }
    t.now = std::stoi((*it)[3].str());
    seen.push_back(t);
  }
  return seen;
}

// With or without OpenMP binding variables (as batch schedulers set them), dem_run's two
// threads may together run on every CPU the program was given; bound to one CPU each
// (OMP_PLACES=threads), they run on two different ones. Before the fix the re-execution that
// applies the wait policy inherited the first place libgomp had bound the initial thread to,
// and both threads ran on CPU 0. Both with the re-execution (passive) and without it (spin).
TEST(dem_ThreadWait, ThreadsUseEveryCoreTheyWereGiven) {
  cpu_set_t mask;
  CPU_ZERO(&mask);
  ASSERT_EQ(::sched_getaffinity(0, sizeof mask, &mask), 0);
  std::set<int> given;
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &mask)) given.insert(c);
  ASSERT_FALSE(given.empty());
  for (const std::string env : {"", "OMP_PROC_BIND=close OMP_PLACES=cores",
                                "OMP_PROC_BIND=close OMP_PLACES=threads", "OMP_PROC_BIND=spread"}) {
    for (const char* wait : {"passive", "spin"}) {
      const std::string out = run_dem_run(env, wait);
      const std::vector<SeenThread> seen = seen_threads(out);
      ASSERT_EQ(seen.size(), 2u) << env << ", " << wait << ":\n" << out;
      std::set<int> together;
      for (const SeenThread& t : seen) {
        together.insert(t.allowed.begin(), t.allowed.end());
        EXPECT_TRUE(t.allowed.count(t.now)) << env << ", " << wait << ": ran outside its mask";
      }
      EXPECT_EQ(together, given) << "with '" << env << "', thread_wait " << wait
                                 << ", the threads may not use every CPU given:\n" << out;
      if (env.find("OMP_PLACES=threads") != std::string::npos && given.size() >= 2) {
        // One CPU each, and not the same one.
        EXPECT_EQ(seen[0].allowed.size(), 1u) << out;
        EXPECT_EQ(seen[1].allowed.size(), 1u) << out;
        EXPECT_NE(seen[0].allowed, seen[1].allowed) << out;
        EXPECT_NE(seen[0].now, seen[1].now) << out;
      }
    }
  }
  fs::remove_all(fs::temp_directory_path() / ("dem_thread_wait_" + std::to_string(::getpid())));
}

}  // namespace
