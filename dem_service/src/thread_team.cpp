#include "dem/thread_team.hpp"

#include <sched.h>

#include <stdexcept>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace dem {

namespace {

inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#endif
}

// Pause iterations before the first yield: a wait this short (about a microsecond) costs less
// spun than a system call.
constexpr int kSpins = 64;

}  // namespace

ThreadTeam::ThreadTeam(int threads, const std::vector<std::vector<int>>& cpus)
    : threads_(threads) {
  if (threads < 1)
    throw std::invalid_argument("ThreadTeam: " + std::to_string(threads) +
                                " threads; use 1 or more");
  errors_.resize(static_cast<std::size_t>(threads));
  workers_.reserve(static_cast<std::size_t>(threads - 1));
  for (int t = 1; t < threads; ++t) {
    std::vector<int> mine = static_cast<std::size_t>(t) < cpus.size()
                                ? cpus[static_cast<std::size_t>(t)]
                                : std::vector<int>{};
    workers_.emplace_back([this, t, mine] { work(t, mine); });
  }
}

ThreadTeam::~ThreadTeam() {
  stop_.store(true, std::memory_order_seq_cst);
  generation_.fetch_add(1, std::memory_order_seq_cst);
  generation_.notify_all();  // whether or not a worker sleeps
  for (std::thread& w : workers_) w.join();
}

void ThreadTeam::wait_while(const std::atomic<std::uint32_t>& word, std::uint32_t old) {
  if (word.load(std::memory_order_acquire) != old) return;
  for (int i = 0; i < kSpins; ++i) {
    cpu_relax();
    if (word.load(std::memory_order_acquire) != old) {
      waits_awake_.fetch_add(1, std::memory_order_relaxed);
      return;
    }
  }
  const auto start = std::chrono::steady_clock::now();
  do {
    ::sched_yield();  // runs another thread that waits for this core, else returns at once
    if (word.load(std::memory_order_acquire) != old) {
      waits_awake_.fetch_add(1, std::memory_order_relaxed);
      return;
    }
  } while (std::chrono::steady_clock::now() - start < kYieldFor);
  // Sleep. The waker changes the word and then reads sleepers_; this thread counts itself in
  // sleepers_ and then reads the word (both sequentially consistent), so either the waker sees
  // a sleeper and notifies, or this thread sees the new word and does not sleep.
  sleepers_.fetch_add(1, std::memory_order_seq_cst);
  while (word.load(std::memory_order_seq_cst) == old) word.wait(old, std::memory_order_seq_cst);
  sleepers_.fetch_sub(1, std::memory_order_release);
  waits_slept_.fetch_add(1, std::memory_order_relaxed);
}

void ThreadTeam::wake(std::atomic<std::uint32_t>& word) {
  if (sleepers_.load(std::memory_order_seq_cst) > 0) word.notify_all();
}

namespace {
// Thrown at a barrier of a run where another thread failed: unwinds this thread too.
struct Abandoned {};
}  // namespace

void ThreadTeam::run_one(int t) {
  try {
    fn_(arg_, t);
  } catch (const Abandoned&) {
    // Another thread's exception is the run's error.
  } catch (...) {
    errors_[static_cast<std::size_t>(t)] = std::current_exception();
    // The threads waiting at a barrier for this one would wait forever: release them.
    failed_.store(true, std::memory_order_seq_cst);
    barrier_gen_.fetch_add(1, std::memory_order_seq_cst);
    barrier_gen_.notify_all();
  }
}

void ThreadTeam::work(int t, std::vector<int> cpus) {
  if (!cpus.empty()) {
    cpu_set_t set;
    CPU_ZERO(&set);
    for (const int c : cpus)
      if (c >= 0 && c < CPU_SETSIZE) CPU_SET(c, &set);
    ::sched_setaffinity(0, sizeof set, &set);  // this thread; on failure it keeps its mask
  }
  std::uint32_t seen = 0;
  for (;;) {
    wait_while(generation_, seen);
    seen = generation_.load(std::memory_order_acquire);
    if (stop_.load(std::memory_order_acquire)) return;
    run_one(t);
    if (left_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
      finished_.fetch_add(1, std::memory_order_seq_cst);
      wake(finished_);
    }
  }
}

void ThreadTeam::run_impl(void (*fn)(void*, int), void* arg) {
  fn_ = fn;
  arg_ = arg;
  for (std::exception_ptr& e : errors_) e = nullptr;
  failed_.store(false, std::memory_order_relaxed);
  arrived_.store(0, std::memory_order_relaxed);
  if (threads_ > 1) {
    const std::uint32_t done0 = finished_.load(std::memory_order_acquire);
    left_.store(threads_ - 1, std::memory_order_relaxed);
    generation_.fetch_add(1, std::memory_order_seq_cst);  // publishes fn_, arg_, left_
    wake(generation_);
    run_one(0);
    wait_while(finished_, done0);
  } else {
    run_one(0);
  }
  for (const std::exception_ptr& e : errors_)
    if (e) std::rethrow_exception(e);
}

void ThreadTeam::barrier(int /*t*/) {
  if (threads_ == 1) return;
  const std::uint32_t g = barrier_gen_.load(std::memory_order_acquire);
  if (failed_.load(std::memory_order_acquire)) throw Abandoned{};
  if (arrived_.fetch_add(1, std::memory_order_acq_rel) + 1 == threads_) {
    arrived_.store(0, std::memory_order_relaxed);
    barrier_gen_.fetch_add(1, std::memory_order_seq_cst);
    wake(barrier_gen_);
  } else {
    wait_while(barrier_gen_, g);
  }
  if (failed_.load(std::memory_order_acquire)) throw Abandoned{};
}

ThreadTeam::Waits ThreadTeam::waits() const {
  return {waits_awake_.load(std::memory_order_relaxed), waits_slept_.load(std::memory_order_relaxed)};
}

}  // namespace dem
