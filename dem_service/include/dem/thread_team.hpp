// The DEM step's own threads (scene.thread_wait: yield): a fixed team of T threads (the caller
// and T - 1 workers started once) that runs one function on every thread and waits at barriers,
// where an idle thread first spins, then yields its core to any other runnable thread, and
// sleeps only after ThreadTeam::kYieldFor without the awaited event.
//
// Why not OpenMP's own waiting: libgomp's idle threads either sleep at once (passive), so that
// every parallel region and barrier pays a wake-up (tens of microseconds in a VM, several per
// DEM step), or spin without yielding (brief, spin), so that two jobs on the same cores take
// each other's cores (docs/performance.md, "Threads on a shared machine"). A thread that yields
// while it waits runs at once when it is alone and gives way when another thread needs its core.
//
// Used by Engine::step_one_region only; the engine's other parallel regions (broad phase,
// output) stay OpenMP's, which then waits passively.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <exception>
#include <thread>
#include <vector>

namespace dem {

class ThreadTeam {
 public:
  // How long a waiting thread spins and yields before it sleeps.
  static constexpr std::chrono::microseconds kYieldFor{1000};

  // threads >= 1: the caller is thread 0, threads - 1 workers start here. cpus[t] (if given
  // and not empty): the CPUs worker t may run on, e.g. those libgomp gave OpenMP's thread t
  // (dem::thread_cpus), so that OMP_PROC_BIND / OMP_PLACES place these threads as they place
  // OpenMP's (a thread started by the bound initial thread would inherit its one place).
  explicit ThreadTeam(int threads, const std::vector<std::vector<int>>& cpus = {});
  ~ThreadTeam();
  ThreadTeam(const ThreadTeam&) = delete;
  ThreadTeam& operator=(const ThreadTeam&) = delete;

  int size() const { return threads_; }

  // fn(t) on thread t = 0 .. size() - 1 (0 on the caller); returns when every thread is done.
  // An exception thrown on any thread is rethrown here (the lowest thread's) after all are
  // done; the other threads leave fn at their next barrier (which throws to unwind them).
  template <class F>
  void run(F& fn) {
    run_impl(&call<F>, &fn);
  }
  // Inside run: every thread of the team waits here until all have come (and sees what the
  // others wrote before they came).
  void barrier(int t);

  // Waits of the calling team so far: how many ended while spinning or yielding, and how many
  // slept (for the docs' measurements and the tests).
  struct Waits {
    std::int64_t awake = 0, slept = 0;
  };
  Waits waits() const;

 private:
  template <class F>
  static void call(void* f, int t) {
    (*static_cast<F*>(f))(t);
  }
  void run_impl(void (*fn)(void*, int), void* arg);
  void work(int t, std::vector<int> cpus);
  void run_one(int t);
  // Waits until word != old: spin, yield, then sleep (futex, through std::atomic::wait).
  void wait_while(const std::atomic<std::uint32_t>& word, std::uint32_t old);
  void wake(std::atomic<std::uint32_t>& word);

  const int threads_;
  void (*fn_)(void*, int) = nullptr;
  void* arg_ = nullptr;
  std::atomic<std::uint32_t> generation_{0};  // one more per run
  std::atomic<std::uint32_t> finished_{0};    // one more per run whose workers are all done
  std::atomic<int> left_{0};                  // workers still in this run
  std::atomic<int> arrived_{0};               // at the barrier
  std::atomic<std::uint32_t> barrier_gen_{0};
  std::atomic<int> sleepers_{0};
  std::atomic<bool> stop_{false};
  std::atomic<bool> failed_{false};  // a thread of this run threw
  std::atomic<std::int64_t> waits_awake_{0}, waits_slept_{0};
  std::vector<std::exception_ptr> errors_;
  std::vector<std::thread> workers_;
};

}  // namespace dem
