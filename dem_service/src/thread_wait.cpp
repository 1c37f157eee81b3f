#include "dem/thread_wait.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace dem {

namespace {

ThreadWaitInForce g_in_force;

std::string describe(ThreadWait w) {
  switch (w) {
    case ThreadWait::passive:
      return "passive (OMP_WAIT_POLICY=PASSIVE: waiting threads sleep at once)";
    case ThreadWait::brief:
      return "brief (GOMP_SPINCOUNT=" + std::to_string(kBriefSpinCount) +
             ": waiting threads spin briefly, then sleep)";
    case ThreadWait::spin:
      break;
  }
  return "spin (libgomp's default: waiting threads spin up to 300000 iterations, then sleep)";
}

}  // namespace

const char* thread_wait_name(ThreadWait w) {
  switch (w) {
    case ThreadWait::passive:
      return "passive";
    case ThreadWait::brief:
      return "brief";
    case ThreadWait::spin:
      break;
  }
  return "spin";
}

const char* thread_wait_choices() { return "passive | brief | spin"; }

ThreadWaitPlan plan_thread_wait(ThreadWait want, const char* omp_wait_policy,
                                const char* gomp_spincount, const char* guard) {
  ThreadWaitPlan p;
  const std::string name = thread_wait_name(want);
  if (!guard && (omp_wait_policy || gomp_spincount)) {
    // Set by the user (or a script) before the program started: the user wins.
    p.action = ThreadWaitPlan::Action::user_environment;
    p.note = "as the environment says (";
    if (omp_wait_policy) p.note += std::string("OMP_WAIT_POLICY=") + omp_wait_policy;
    if (omp_wait_policy && gomp_spincount) p.note += ", ";
    if (gomp_spincount) p.note += std::string("GOMP_SPINCOUNT=") + gomp_spincount;
    p.note += "; scene.thread_wait '" + name + "' not applied)";
    return p;
  }
  p.note = describe(want);
  if (guard && name == guard) return p;  // re-executed for this policy already
  if (!guard && want == ThreadWait::spin) return p;  // nothing set: libgomp's default is spin
  // Either nothing is set and the policy needs a variable, or an earlier re-execution set the
  // variables for another policy (they are ours, not the user's): set them for this one.
  p.action = ThreadWaitPlan::Action::reexec;
  p.unset = {"OMP_WAIT_POLICY", "GOMP_SPINCOUNT"};
  switch (want) {
    case ThreadWait::passive:
      p.set.emplace_back("OMP_WAIT_POLICY", "PASSIVE");
      break;
    case ThreadWait::brief:
      p.set.emplace_back("GOMP_SPINCOUNT", std::to_string(kBriefSpinCount));
      break;
    case ThreadWait::spin:
      break;
  }
  p.set.emplace_back(kThreadWaitGuard, name);
  return p;
}

std::string apply_thread_wait(ThreadWait want, char** argv) {
  const ThreadWaitPlan p = plan_thread_wait(want, std::getenv("OMP_WAIT_POLICY"),
                                            std::getenv("GOMP_SPINCOUNT"),
                                            std::getenv(kThreadWaitGuard));
  if (p.action == ThreadWaitPlan::Action::user_environment) {
    g_in_force = {true, true, want};
    return p.note;
  }
  if (p.action == ThreadWaitPlan::Action::none) {
    g_in_force = {true, false, want};
    return p.note;
  }
  // What the runtime loaded with, should the re-execution fail.
  const char* old_guard = std::getenv(kThreadWaitGuard);
  const std::string old = old_guard ? old_guard : "spin";
  for (const auto& v : p.unset) ::unsetenv(v.c_str());
  for (const auto& [k, v] : p.set) ::setenv(k.c_str(), v.c_str(), 1);
  std::fflush(nullptr);
  ::execv("/proc/self/exe", argv);
  const int err = errno;  // execv returned: the runtime keeps what it loaded with
  std::fprintf(stderr,
               "warning: could not re-execute to make OpenMP threads wait '%s' (execv "
               "/proc/self/exe: %s); they wait as before ('%s')\n",
               thread_wait_name(want), std::strerror(err), old.c_str());
  g_in_force = {true, false, old == "passive" ? ThreadWait::passive
                             : old == "brief" ? ThreadWait::brief
                                              : ThreadWait::spin};
  return describe(g_in_force.policy);
}

ThreadWaitInForce thread_wait_in_force() { return g_in_force; }

}  // namespace dem
