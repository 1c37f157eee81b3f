// How the DEM's OpenMP threads wait between parallel regions (scene.thread_wait).
//
// GCC's OpenMP runtime (libgomp) lets a thread that waits at a barrier or for the next parallel
// region spin for GOMP_SPINCOUNT iterations (300,000 by default) before it sleeps. One DEM alone
// on the machine gains a little from that; two DEM processes on the same cores lose ~10x,
// because each one's spinning threads take the cores the other one's working threads need.
//
// libgomp reads OMP_WAIT_POLICY and GOMP_SPINCOUNT once, when it is loaded (before main()), and
// offers no call to change them later. So a program that wants a policy other than the one its
// environment gave it re-executes itself once (execv of /proc/self/exe, same arguments) with the
// variables set, marked by DEM_THREAD_WAIT_APPLIED so it happens once. A user who sets
// OMP_WAIT_POLICY or GOMP_SPINCOUNT himself wins: the config's policy is then not applied.
//
// With OMP_PROC_BIND set, libgomp binds the initial thread to the first OpenMP place when it
// loads; the re-executed program would inherit that single place as its whole affinity mask and
// run every thread on one core. The re-execution therefore first widens the mask back to all the
// places' CPUs (the CPUs the program was given).
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace dem {

enum class ThreadWait {
  passive,  // sleep at once (OMP_WAIT_POLICY=PASSIVE)
  brief,    // spin briefly, then sleep (GOMP_SPINCOUNT=kBriefSpinCount)
  spin,     // libgomp's default: spin up to 300,000 iterations, then sleep
  // The DEM step runs on the engine's own threads (dem/thread_team.hpp), which wait by
  // spinning, then yielding the core to any other runnable thread, and sleep after 1 ms;
  // OpenMP's other regions wait passively (OMP_WAIT_POLICY=PASSIVE).
  yield,
};

// Every policy, in the order thread_wait_choices() lists them.
inline constexpr ThreadWait kThreadWaits[] = {ThreadWait::passive, ThreadWait::brief,
                                              ThreadWait::spin, ThreadWait::yield};

// Spin iterations of `brief` (libgomp's default is 300,000).
constexpr long long kBriefSpinCount = 10000;

// The config spelling: "passive", "brief", "spin", "yield".
const char* thread_wait_name(ThreadWait w);
// The allowed values as the config error lists them: "passive | brief | spin | yield".
const char* thread_wait_choices();

// The environment variable that marks a process re-executed for a policy (its value is the
// policy's name).
constexpr const char* kThreadWaitGuard = "DEM_THREAD_WAIT_APPLIED";

// What a process must do so that its threads wait as `want` says, given the values (nullptr =
// unset) of OMP_WAIT_POLICY, GOMP_SPINCOUNT and the guard it started with. Pure: no
// environment read or written.
struct ThreadWaitPlan {
  enum class Action {
    none,              // the runtime already waits as wanted
    user_environment,  // the user set OMP_WAIT_POLICY / GOMP_SPINCOUNT: keep them
    reexec,            // set `set`, unset `unset`, execute the program again
  };
  Action action = Action::none;
  std::vector<std::pair<std::string, std::string>> set;
  std::vector<std::string> unset;
  std::string note;  // how the threads wait, for the program's log line
};
ThreadWaitPlan plan_thread_wait(ThreadWait want, const char* omp_wait_policy,
                                const char* gomp_spincount, const char* guard);

// Applies plan_thread_wait to this process: returns the note when nothing needs doing, or
// re-executes the program with argv (does not return). If the re-execution fails, it prints
// why on stderr and returns, the threads waiting as the environment says. Call it before the
// first OpenMP region and before anything is written (the re-executed program starts over).
std::string apply_thread_wait(ThreadWait want, char** argv);

// The policy apply_thread_wait found in force (or put in force) in this process, and whether
// the user's environment decided it; `known` is false before apply_thread_wait ran.
struct ThreadWaitInForce {
  bool known = false;
  bool from_user_environment = false;
  ThreadWait policy = ThreadWait::spin;
};
ThreadWaitInForce thread_wait_in_force();

// The CPUs each of `threads` OpenMP threads may run on (its affinity mask) and the one it was
// running on when asked, from one parallel region: that the threads use every core they were
// given, with or without OMP_PROC_BIND / OMP_PLACES (apply_thread_wait's re-execution restores
// the mask libgomp narrowed to the first place).
struct ThreadCpus {
  std::vector<int> allowed;  // sched_getaffinity, ascending
  int now = -1;              // sched_getcpu
};
std::vector<ThreadCpus> thread_cpus(int threads);
// "thread 0 on CPUs 0 (running on 0); thread 1 on CPUs 1 (running on 1)" for the start-up log.
std::string describe_thread_cpus(const std::vector<ThreadCpus>& threads);

}  // namespace dem
