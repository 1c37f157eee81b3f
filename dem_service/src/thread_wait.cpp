#include "dem/thread_wait.hpp"

#include "dem/thread_team.hpp"

#include <omp.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <vector>

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
    case ThreadWait::yield:
      return "yield (the DEM step's own threads spin, yield the core to any other runnable "
             "thread, and sleep after " +
             std::to_string(ThreadTeam::kYieldFor.count()) +
             " us; OpenMP's other regions: OMP_WAIT_POLICY=PASSIVE)";
    case ThreadWait::spin:
      break;
  }
  return "spin (libgomp's default: waiting threads spin up to 300000 iterations, then sleep)";
}

// The CPUs of all OpenMP places (libgomp made them from the affinity mask the process started
// with), or none when no place list is in force (no binding asked for).
std::vector<int> place_cpus() {
  std::set<int> cpus;
  const int places = omp_get_num_places();
  for (int p = 0; p < places; ++p) {
    const int n = omp_get_place_num_procs(p);
    if (n <= 0) continue;
    std::vector<int> ids(static_cast<std::size_t>(n));
    omp_get_place_proc_ids(p, ids.data());
    cpus.insert(ids.begin(), ids.end());
  }
  return {cpus.begin(), cpus.end()};
}

// With OMP_PROC_BIND set, libgomp binds the initial thread to the first place when it loads,
// and a re-executed program inherits that one place as its whole affinity mask: its places,
// and so all its threads, would be that one core. Before the re-execution the mask is widened
// back to every CPU of the places, the CPUs the program was given. Without binding there is no
// place list and the mask is left as it is (libgomp did not narrow it).
void restore_affinity_for_reexec() {
  const std::vector<int> cpus = place_cpus();
  if (cpus.empty()) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  for (const int c : cpus)
    if (c >= 0 && c < CPU_SETSIZE) CPU_SET(c, &set);
  if (::sched_setaffinity(0, sizeof set, &set) != 0)
    std::fprintf(stderr,
                 "warning: could not restore the CPU affinity before re-executing (%s); with "
                 "OMP_PROC_BIND set, the OpenMP threads may share one CPU\n",
                 std::strerror(errno));
}

}  // namespace

std::vector<ThreadCpus> thread_cpus(int threads) {
  std::vector<ThreadCpus> out(static_cast<std::size_t>(std::max(1, threads)));
#pragma omp parallel num_threads(static_cast<int>(out.size()))
  {
    const int t = omp_get_thread_num();
    if (t < static_cast<int>(out.size())) {
      ThreadCpus& c = out[static_cast<std::size_t>(t)];
      cpu_set_t set;
      CPU_ZERO(&set);
      if (::sched_getaffinity(0, sizeof set, &set) == 0)
        for (int k = 0; k < CPU_SETSIZE; ++k)
          if (CPU_ISSET(k, &set)) c.allowed.push_back(k);
      c.now = ::sched_getcpu();
    }
  }
  return out;
}

std::string describe_thread_cpus(const std::vector<ThreadCpus>& threads) {
  std::string s;
  for (std::size_t t = 0; t < threads.size(); ++t) {
    if (t) s += "; ";
    s += "thread " + std::to_string(t) + " on CPUs ";
    const std::vector<int>& a = threads[t].allowed;
    // Ranges: 0-3,6
    for (std::size_t k = 0; k < a.size();) {
      std::size_t e = k;
      while (e + 1 < a.size() && a[e + 1] == a[e] + 1) ++e;
      if (k) s += ",";
      s += std::to_string(a[k]);
      if (e > k) s += "-" + std::to_string(a[e]);
      k = e + 1;
    }
    if (a.empty()) s += "?";
    s += " (running on " + std::to_string(threads[t].now) + ")";
  }
  return s;
}

const char* thread_wait_name(ThreadWait w) {
  switch (w) {
    case ThreadWait::passive:
      return "passive";
    case ThreadWait::brief:
      return "brief";
    case ThreadWait::yield:
      return "yield";
    case ThreadWait::spin:
      break;
  }
  return "spin";
}

const char* thread_wait_choices() { return "passive | brief | spin | yield"; }

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
    case ThreadWait::yield:
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
  restore_affinity_for_reexec();
  std::fflush(nullptr);
  ::execv("/proc/self/exe", argv);
  const int err = errno;  // execv returned: the runtime keeps what it loaded with
  std::fprintf(stderr,
               "warning: could not re-execute to make OpenMP threads wait '%s' (execv "
               "/proc/self/exe: %s); they wait as before ('%s')\n",
               thread_wait_name(want), std::strerror(err), old.c_str());
  ThreadWait loaded = ThreadWait::spin;
  for (const ThreadWait w : kThreadWaits)
    if (old == thread_wait_name(w)) loaded = w;
  g_in_force = {true, false, loaded};
  return describe(g_in_force.policy);
}

ThreadWaitInForce thread_wait_in_force() { return g_in_force; }

}  // namespace dem
