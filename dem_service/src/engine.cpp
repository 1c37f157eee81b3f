#include "dem/engine.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <utility>

#include "dem/rotation.hpp"
#include "dem/stability.hpp"

namespace dem {
namespace {

// One step of semi-implicit Euler: the new velocity moves the particle (symplectic, one force
// evaluation per step; docs/physics.md); u is the velocity at the next force time. Returns |v|^2.
inline double advance(double dt, double m, const Vec3& f, Vec3& v, Vec3& u, Vec3& x) {
  // Component by component (the same arithmetic as with Vec3 temporaries): through a Vec3
  // the compiler built vn on the stack and copied it with a 16-byte load of two 8-byte stores,
  // a store-forwarding stall per particle.
  const double c = dt / m;
  const double dvx = c * f.x, dvy = c * f.y, dvz = c * f.z;
  const double vx = v.x + dvx, vy = v.y + dvy, vz = v.z + dvz;
  v.x = vx;
  v.y = vy;
  v.z = vz;
  u.x = vx + 0.5 * dvx;
  u.y = vy + 0.5 * dvy;
  u.z = vz + 0.5 * dvz;
  x.x = x.x + dt * vx;
  x.y = x.y + dt * vy;
  x.z = x.z + dt * vz;
  return vx * vx + vy * vy + vz * vz;
}

// Waits until ready() (an odd pair block for the even ones beside it): spins with a pause, then
// yields. Returns the seconds waited.
template <class Ready>
double wait_until(Ready&& ready) {
  if (ready()) return 0;
  const cosim::Stopwatch wait;
  int spins = 0;
  while (!ready()) {
    if (++spins < 4000) {
#if defined(__x86_64__) || defined(__i386__)
      __builtin_ia32_pause();
#endif
    } else {
      std::this_thread::yield();
    }
  }
  return wait.seconds();
}

}  // namespace

Timing make_timing() {
  return Timing({"broad_phase", "pair_forces", "mesh_contacts", "integration", "output"});
}

Engine::Engine(const Scene& scene, const EngineOptions& options)
    : scene_(scene),
      options_(options),
      max_threads_(std::max(1, scene.threads)),
      tools_(scene),
      sleepers_(scene, std::max(1, scene.threads)),
      boundary_(scene, std::max(1, scene.threads)) {
  threads_ = max_threads_;
  remote_.resize(max_threads_);
  thread_stats_.assign(max_threads_, ContactStats{});
  broad_.use_vector_row_test(options.vector_row_test);
  broad_.use_history_same_rows(options.history_same_rows);
  boundary_.use_fast_path(options.boundary_fast);
  boundary_.use_triangle_lanes(options.vector_triangle_test);
  reset_thread_busy();
  validate_rotation(scene);  // the rotating model's rules (ranges)
}

double Engine::thread_busy(std::size_t sec, int t) const {
  if (sec < section::pair_forces || sec > section::integration || t < 0 || t >= max_threads_)
    return 0;
  return busy_[sec * static_cast<std::size_t>(max_threads_) + static_cast<std::size_t>(t)];
}

void Engine::reset_thread_busy() {
  busy_.assign((section::integration + 1) * static_cast<std::size_t>(max_threads_), 0.0);
}

void Engine::choose_threads(const State& s) {
  const long per = std::max(1, options_.min_particles_per_thread);
  const long cap = std::max(1L, static_cast<long>(s.size()) / per);
  threads_ = static_cast<int>(std::min<long>(max_threads_, cap));
}

// --- Stage 1: the lists (geometry, region of interest, broad phase or the guard).

void Engine::build_lists(State& s) {
  sleepers_.remove_outside(s);
  choose_threads(s);
  broad_.build(scene_, s, tools_.vertices, threads_);
}

void Engine::rebuild(State& s) {
  if (scene_.rotation.rotating()) Rotation::size_arrays(s);
  choose_threads(s);
  cosim::Stopwatch watch;
  tools_.update(scene_, s);
  Sleepers::size_arrays(s);
  build_lists(s);
  timing_.lap(section::broad_phase, watch);
}

void Engine::prepare(State& s) {
  if (scene_.rotation.rotating()) Rotation::size_arrays(s);
  choose_threads(s);
  cosim::Stopwatch watch;
  tools_.update(scene_, s);
  timing_.lap(section::mesh_contacts, watch);
  Sleepers::size_arrays(s);
  sleepers_.clear_removed();

  const bool due = !s.lists_valid || s.steps_since_rebuild >= scene_.broad_phase_interval ||
                   s.pair_offset.size() != s.size() + 1 || s.slot_block.size() != s.size() ||
                   s.slot_particle.size() * kBoundarySlots != s.slot_key.size() ||
                   s.pair_work.size() != s.size() + 1;
  double moved = 0;
  if (ghost_) {
    // Decomposed (set_ghosts): the caller rebuilds every rank at the same step, with the
    // guard's bound over all ranks (dem/mpi/); a broad phase here would lose the ghosts.
    if (due || ghost_->size() != s.size())
      throw std::logic_error("Engine::prepare: lists due under domain decomposition at step " +
                             std::to_string(s.step) + "; the MPI driver must rebuild first");
  } else if (due) {
    build_lists(s);
  } else if (guard_.fires(scene_, s, &moved)) {
    if (scene_.guard == GuardMode::rebuild && guard_.clear(scene_, s, broad_, tools_)) {
      guard_.count_cleared(s);
      timing_.lap(section::broad_phase, watch);
      return;
    }
    if (scene_.guard == GuardMode::strict)
      throw SimulationError(FarMoverGuard::strict_message(scene_, s, moved));
    ++s.early_rebuilds;
    build_lists(s);
  }
  timing_.lap(section::broad_phase, watch);
}

void Engine::step(State& s) {
  prepare(s);
  if (options_.one_region && !scene_.rotation.rotating() &&
      options_.pair_schedule == PairSchedule::blocks) {
    if (scene_.sleep.enabled)
      step_one_region<true>(s);
    else
      step_one_region<false>(s);
    return;
  }
  cosim::Stopwatch watch;
  // The rotating model (dem/rotation.hpp) has its own pair loop and spin integration; the
  // translating model's loops are not touched by it.
  const bool rotating = scene_.rotation.rotating();
  if (rotating)
    rotating_pair_forces(s);
  else
    pair_forces(s);
  timing_.lap(section::pair_forces, watch);
  boundary_.forces(s, tools_, force_.data(), threads_, busy_row(section::mesh_contacts),
                   rotating ? rotation_.torque() : nullptr, ghost_ ? ghost_->data() : nullptr);
  timing_.lap(section::mesh_contacts, watch);
  sum_contact_stats();
  watch.restart();
  // The spins first: the fall-asleep test in integrate() reads the new w (|v| + |w| r).
  if (rotating) rotation_.integrate(scene_, s);
  integrate(s);
  timing_.lap(section::integration, watch);
}

void Engine::sum_contact_stats() {
  stats_ = ContactStats{};
  for (int t = 0; t < threads_; ++t)
    for (const ContactStats* c : {&std::as_const(thread_stats_[t]), &boundary_.thread_stats(t)}) {
      stats_.particle_contacts += c->particle_contacts;
      stats_.boundary_contacts += c->boundary_contacts;
      stats_.max_overlap = std::max(stats_.max_overlap, c->max_overlap);
      stats_.max_overlap_ratio = std::max(stats_.max_overlap_ratio, c->max_overlap_ratio);
    }
}

// --- Stage 2: pair forces.

// The forces on particles [i0, i1) start from gravity, and with sleeping no one has woken them
// yet. A sleeper's force is not written: nothing reads it (the integration passes sleepers, one
// woken in this step is integrated from the next on, with the forces of that step; the pair
// loop adds nothing to it), and its store was most of this loop's memory traffic. With the
// awake list (EngineOptions::awake_list) only the awake particles of the range are visited.
template <bool Sleep>
void Engine::start_forces(const State& s, std::size_t i0, std::size_t i1) {
  const Vec3 g = scene_.gravity;
  if (Sleep) {
    const double* __restrict const M = s.mass.data();
    Vec3* __restrict const F = force_.data();
    std::uint8_t* __restrict const WAKE = sleepers_.wake();
    if (i1 > i0) std::memset(WAKE + i0, 0, i1 - i0);
    if (awake_now_) {
      const std::int32_t* const A = awake_now_->data();
      const std::int32_t* q = std::lower_bound(A, A + awake_now_->size(), static_cast<std::int32_t>(i0));
      const std::int32_t* const end = A + awake_now_->size();
      for (; q != end && static_cast<std::size_t>(*q) < i1; ++q) F[*q] = M[*q] * g;
      return;
    }
    const std::int32_t S = scene_.sleep.steps;
    const std::int32_t* __restrict const REST = s.rest_steps.data();
    for (std::size_t i = i0; i < i1; ++i)
      if (REST[i] < S) F[i] = M[i] * g;
  } else {
    for (std::size_t i = i0; i < i1; ++i) force_[i] = s.mass[i] * g;
  }
}

void Engine::rotating_pair_forces(State& s) {
  const cosim::Stopwatch busy;
  split_.clear();  // the integration splits the particles evenly
  for (int t = 0; t < threads_; ++t) thread_stats_[t] = ContactStats{};
  awake_now_ = nullptr;
  if (scene_.sleep.enabled) {
    // The translating model's sleeping rules in the rotating pair loop (one thread, every wake
    // direct); the integration is the translating one's (awake list, wake tests).
    detail::PairSleep rules = sleepers_.pair_rules(s, false);
    if (s.size() > 0) std::memset(rules.wake, 0, s.size());
    rules.woken = &sleepers_.woken(0);
    if (options_.awake_list) awake_now_ = &sleepers_.awake(s);
    rotation_.pair_forces(scene_, s, force_, thread_stats_[0], &rules);
  } else {
    rotation_.pair_forces(scene_, s, force_, thread_stats_[0]);
  }
  add_busy(section::pair_forces, 0, busy.seconds());
}

void Engine::pair_forces(State& s) {
  if (scene_.sleep.enabled)
    pair_forces_impl<true>(s);
  else
    pair_forces_impl<false>(s);
}

detail::Kernel Engine::pair_kernel() const {
  switch (options_.pair_kernel) {
    case EngineOptions::PairKernel::scalar:
      return detail::Kernel::scalar;
    case EngineOptions::PairKernel::emulated:
      return detail::Kernel::emulated;
    case EngineOptions::PairKernel::avx2:
      return detail::Kernel::avx2;
    case EngineOptions::PairKernel::vector:
      break;
  }
  return detail::Kernel::vector;
}

// Threads take contiguous particle ranges of equal work (State::pair_work), not of equal
// length: the bottom of a bed has about twice the contacts of its top half.
void Engine::split_pair_work(const State& s) {
  const std::size_t n = s.size();
  const int T = threads_;
  bounds_.resize(T + 1);
  const std::int64_t* const work = s.pair_work.data();
  bounds_[0] = 0;
  bounds_[T] = n;
  for (int t = 1; t < T; ++t) {
    const std::int64_t target = work[n] * t / T;
    bounds_[t] = static_cast<std::size_t>(
        std::lower_bound(work + bounds_[t - 1], work + n, target) - work);
  }
}

// What every thread's rows read and write (raw pointers, see dem/pair_kernel.hpp): the half
// list, or the close pairs where they are on and in use.
detail::PairRows Engine::pair_rows_of(State& s) {
  detail::PairRows rows;
  rows.x = s.x.data();
  rows.u = s.u.data();
  rows.radius = s.radius.data();
  rows.mass = s.mass.data();
  rows.offset = s.pair_offset.data();
  rows.partner = s.pair_j.data();
  rows.spring = s.pair_spring.data();
  rows.force = force_.data();
  rows.law = scene_.particle_particle;
  rows.dt = scene_.dt;
  rows.branch_free_chunks =
      options_.pair_chunks == EngineOptions::PairChunks::processor
          ? detail::branch_free_chunks_default()
          : options_.pair_chunks == EngineOptions::PairChunks::branch_free;
  rows.screened = options_.pair_passes == EngineOptions::PairPasses::two ||
                  (options_.pair_passes == EngineOptions::PairPasses::automatic &&
                   s.size() <= EngineOptions::kScreenedMaxParticles);
  rows.queued_rows = options_.queued_rows;
  if (close_pairs_on(scene_, options_)) {
    const double margin = close_distance(scene_, options_);
    if (!close_.hold(scene_, margin, s)) close_.list(scene_, margin, s, bounds_, threads_);
    if (close_.use()) {
      rows.offset = close_.offset();
      rows.partner = close_.partner();
      rows.spring = close_.spring();
      rows.spring_index = close_.index();
      rows.spring_home = s.pair_spring.data();
    }
  }
  return rows;
}

// Sleep = false is the all-active loop (detail::pair_rows: the AVX-512 kernel or the scalar
// loop, the same bits); Sleep = true adds the sleeper rules (Scene::sleep, detail::pair_rows_sleep)
// and computes every force that the all-active loop computes between awake particles in the
// same order, so the awake part of the bed sees the same sums.
template <bool Sleep>
void Engine::pair_forces_impl(State& s) {
  force_.resize(s.size());
  split_pair_work(s);
  detail::PairSleep rules;  // each thread adds its queue of remote wakes
  awake_now_ = nullptr;
  if (Sleep) {
    rules = sleepers_.pair_rules(s, options_.sleeper_row_skip);
    if (options_.awake_list) awake_now_ = &sleepers_.awake(s);
  }
  const detail::PairRows rows = pair_rows_of(s);
  if (options_.pair_schedule == PairSchedule::blocks)
    pair_forces_blocks<Sleep>(s, rows, rules);
  else
    pair_forces_ranges<Sleep>(s, rows, rules);
}

// One step's pass over the pair blocks: what every thread reads (pair_blocks_thread).
struct Engine::BlockPass {
  detail::PairRows rows;
  detail::PairSleep rules;
  detail::Kernel kernel = detail::Kernel::vector;
  std::size_t n = 0;
  std::int64_t K = 0, pass = 0;
  const std::size_t* B = nullptr;  // the first row of each block and the end
  std::int64_t* DONE = nullptr;
  std::int64_t* CLAIM = nullptr;
  int* owner = nullptr;  // the thread that ran each block
};

Engine::BlockPass Engine::begin_pair_blocks(State& s, const detail::PairRows& rows,
                                            const detail::PairSleep& rules) {
  BlockPass p;
  p.kernel = pair_kernel();
  blocks_.make(s);
  p.n = s.size();
  p.K = blocks_.count();
  p.pass = blocks_.next_pass();
  p.B = blocks_.start().data();
  p.DONE = blocks_.done();
  p.CLAIM = blocks_.claim();
  p.owner = blocks_.owner().data();
  p.rows = rows;
  p.rows.direct_end = p.n;  // a block's partners: in it or in the next block (made so)
  p.rules = rules;
  return p;
}

template <bool Sleep>
void Engine::pair_forces_blocks(State& s, const detail::PairRows& block_rows,
                                const detail::PairSleep& rules) {
  const int T = threads_;
  const BlockPass p = begin_pair_blocks(s, block_rows, rules);
#pragma omp parallel num_threads(T)
  pair_blocks_thread<Sleep>(s, p, omp_get_thread_num(), T);
  split_.resize(static_cast<std::size_t>(T) + 1);
  owner_split(p, T, split_.data());
}

// Thread t's part of a pass over the pair blocks (inside a parallel region of T threads).
template <bool Sleep>
void Engine::pair_blocks_thread(State& s, const BlockPass& p, int t, int T) {
  const std::int64_t K = p.K, pass = p.pass;
  const std::size_t* const B = p.B;
  std::int64_t* const DONE = p.DONE;
  std::int64_t* const CLAIM = p.CLAIM;
  cosim::Stopwatch busy;
  double waited = 0;  // for the even blocks beside an odd one
  std::vector<detail::PairRemote> remote;  // stays empty: every partner is direct
  std::vector<std::int32_t> remote_wake;
  detail::PairSleep sl = p.rules;
  sl.remote_wake = &remote_wake;
  if (Sleep) sl.woken = &sleepers_.woken(t);
  detail::PairRowStats st;
  // This thread's walk: it runs each block that no one has claimed before it. Before an odd
  // block the walk has passed both evens beside it, so they are claimed and, as an even
  // block never waits, done or being done.
  for (const std::int32_t kk : detail::pair_block_walk(static_cast<std::int32_t>(K), t, T)) {
    const std::int64_t k = kk;
    if (!claim_first(CLAIM, k, pass)) continue;
    p.owner[k] = t;
    if (k % 2 == 0) {
      // This block's and the next block's particles start from gravity (no one else
      // writes the next block before this block is done).
      start_forces<Sleep>(s, B[k], B[std::min(k + 2, K)]);
    } else {
      // The even blocks beside it: the one before has set up this block and written into
      // it, the one after is written into by this one.
      waited += wait_until([&] {
        return __atomic_load_n(&DONE[k - 1], __ATOMIC_ACQUIRE) == pass &&
               (k + 1 >= K || __atomic_load_n(&DONE[k + 1], __ATOMIC_ACQUIRE) == pass);
      });
    }
    if (Sleep)
      detail::pair_rows_sleep(p.rows, sl, B[k], B[k + 1], remote, st, p.kernel);
    else
      detail::pair_rows(p.rows, B[k], B[k + 1], remote, st, p.kernel);
    __atomic_store_n(&DONE[k], pass, __ATOMIC_RELEASE);
  }
  thread_stats_[t] = ContactStats{st.contacts, 0, st.max_overlap, st.max_overlap_ratio};
  add_busy(section::pair_forces, t, busy.seconds() - waited);
}

// The integration's ranges follow the blocks' owners (out: T + 1 entries): thread t starts at
// the first block that a thread t or above ran (a split of the particles only, never of a sum).
void Engine::owner_split(const BlockPass& p, int T, std::size_t* out) const {
  out[0] = 0;
  out[T] = p.n;
  for (int t = 1; t < T; ++t) {
    std::int64_t k = 0;
    while (k < p.K && p.owner[k] < t) ++k;
    out[t] = std::max(out[t - 1], p.B[k]);
  }
}

// Thread t's entries of owner_split (out[0], out[1]: its range), without the others'.
void Engine::owner_range(const BlockPass& p, int T, int t, std::size_t* out) const {
  std::size_t split = 0;  // owner_split's entry u, for u = 0 .. t + 1
  for (int u = 1; u <= t + 1; ++u) {
    std::size_t next = p.n;
    if (u < T) {
      std::int64_t k = 0;
      while (k < p.K && p.owner[k] < u) ++k;
      next = std::max(split, p.B[k]);
    }
    if (u == t + 1) {
      out[0] = split;
      out[1] = next;
    }
    split = next;
  }
}

void Engine::region_barrier(int t) {
  if (region_team_) {
    region_team_->barrier(t);
  } else {
#pragma omp barrier
  }
}

// BoundaryContacts::ChunkWait for one region per step: returns once the pair forces of
// particles [lo, hi] are complete, the seconds waited. A particle's force is written by the
// rows of its own block and of the block before it (a row's partners lie in its block or the
// next; an even block starts the forces of the next one), so the blocks from the one before
// lo's to hi's must be done. A thread comes here after its walk over the blocks, when every
// block is claimed: one not done is being run by another thread, which waits for no boundary
// chunk, so the wait ends.
double Engine::wait_for_blocks(const void* ctx, std::size_t lo, std::size_t hi) {
  const BlockPass& p = *static_cast<const BlockPass*>(ctx);
  if (p.K <= 0) return 0;
  auto block_of = [&](std::size_t i) {
    const std::int64_t k = std::upper_bound(p.B, p.B + p.K + 1, i) - p.B - 1;
    return std::clamp<std::int64_t>(k, 0, p.K - 1);
  };
  const std::int64_t k0 = std::max<std::int64_t>(0, block_of(lo) - 1), k1 = block_of(hi);
  return wait_until([&] {
    for (std::int64_t k = k0; k <= k1; ++k)
      if (__atomic_load_n(&p.DONE[k], __ATOMIC_ACQUIRE) != p.pass) return false;
    return true;
  });
}

template <bool Sleep>
void Engine::pair_forces_ranges(State& s, const detail::PairRows& rows,
                                const detail::PairSleep& rules) {
  const int T = threads_;
  const detail::Kernel kernel = pair_kernel();
  split_.assign(bounds_.begin(), bounds_.end());
#pragma omp parallel num_threads(T)
  {
    const int t = omp_get_thread_num();
    const std::size_t a0 = bounds_[t], a1 = bounds_[t + 1];
    const cosim::Stopwatch busy;
    std::vector<detail::PairRemote> remote;  // local for the loop (no false sharing), capacity kept
    remote.swap(remote_[t]);
    remote.clear();
    std::vector<std::int32_t> remote_wake;
    if (Sleep) {
      remote_wake.swap(sleepers_.remote_wake(t));
      remote_wake.clear();
    }
    start_forces<Sleep>(s, a0, a1);
    detail::PairRowStats st;
    if (Sleep) {
      detail::PairSleep sl = rules;
      sl.remote_wake = &remote_wake;
      sl.woken = &sleepers_.woken(t);
      detail::pair_rows_sleep(rows, sl, a0, a1, remote, st, kernel);
    } else {
      detail::pair_rows(rows, a0, a1, remote, st, kernel);
    }
    remote.swap(remote_[t]);
    if (Sleep) remote_wake.swap(sleepers_.remote_wake(t));
    thread_stats_[t] = ContactStats{st.contacts, 0, st.max_overlap, st.max_overlap_ratio};
    add_busy(section::pair_forces, t, busy.seconds());
  }
  for (int t = 0; t < T; ++t)
    for (const detail::PairRemote& r : remote_[t]) force_[r.j] -= r.f;
  if (Sleep) sleepers_.apply_remote_wakes(T);
}

// --- Stage 4: integration.

// The tallies of one thread's particles (merged over the threads after the loop).
struct Engine::StepTally {
  double d1 = 0, d2 = 0;  // the two largest squared displacements (two particles)
  FarMoverGuard::Tally far;  // far movers: the others' largest displacement and speed, the largest
  double close_d1 = 0, close_d2 = 0, close_u2 = 0;  // close pairs (slow particles)
  std::int64_t bad = -1;  // the first particle above the speed limit (or NaN)
  std::int64_t sleeping = 0;
  void merge(const StepTally& o) {
    keep_two_largest(d1, d2, o.d1);
    keep_two_largest(d1, d2, o.d2);
    far.merge(o.far);
    keep_two_largest(close_d1, close_d2, o.close_d1);
    keep_two_largest(close_d1, close_d2, o.close_d2);
    close_u2 = std::max(close_u2, o.close_u2);
    sleeping += o.sleeping;
    if (o.bad >= 0 && (bad < 0 || o.bad < bad)) bad = o.bad;
  }
};

void Engine::integrate(State& s) {
  if (scene_.sleep.enabled)
    integrate_impl<true>(s);
  else
    integrate_impl<false>(s);
}

// What the integration of this step does, decided before it (begin_integration).
struct Engine::IntegrationPlan {
  bool close = false;   // close pairs in use: their tallies are kept
  bool keep = false;    // the sleepers' share of the guard's tallies is kept between steps
  bool renote = false;  // and is noted again from every sleeper in this step
  bool listed = false;  // the awake list's integration (integrate_listed)
};

template <bool Sleep>
Engine::IntegrationPlan Engine::begin_integration(State& s) {
  const int T = threads_;
  IntegrationPlan plan;
  if (Sleep) {
    sleepers_.begin_step();
    sleepers_.make_neighbourhood(s, tools_);
  }
  guard_.size_lists(static_cast<std::size_t>(T));
  // Close pairs in use: the slow particles' displacements since they were listed, and speeds.
  plan.close = close_.in_use_for(s);
  // Sleeping without close pairs: the sleepers' share of the guard's tallies is kept between
  // steps (Sleepers' tally); a particle adds its displacement when it falls asleep.
  plan.keep = Sleep && !plan.close;
  plan.renote = plan.keep && sleepers_.begin_tally(s, T);
  // The awake list: the awake particles and the sleepers a wake test needs, not the whole bed
  // (every sleeper is visited when the tally is noted again, or without the shortcuts).
  plan.listed = plan.keep && !plan.renote && options_.awake_list && options_.sleeper_blocks &&
                awake_now_ != nullptr && sleepers_.awake_holds(s);
  return plan;
}

// After the threads: the tallies of the step, and the step finished.
void Engine::end_integration(State& s, StepTally& total, const IntegrationPlan& plan) {
  const int T = threads_;
  int lists = T;
  if (plan.keep) lists = sleepers_.end_tally(s, T, total.d1, total.d2, total.far, guard_);
  finish_step(s, total, lists, plan.close);
}

template <bool Sleep>
void Engine::integrate_impl(State& s) {
  const std::size_t n = s.size();
  const int T = threads_;
  const IntegrationPlan plan = begin_integration<Sleep>(s);
  StepTally total;
  if (plan.listed) {
    integrate_listed(s, total);
  } else {
#pragma omp parallel num_threads(T)
    {
      const int t = omp_get_thread_num();
      // The particles whose pair forces this thread ran (pair_forces), which are in its cache.
      const bool own = split_.size() == static_cast<std::size_t>(T) + 1 && split_[T] == n;
      const std::size_t a0 = own ? split_[t] : n * t / T, a1 = own ? split_[t + 1] : n * (t + 1) / T;
      integrate_walk_thread<Sleep>(s, a0, a1, plan.keep, plan.renote, total, t);
    }
  }
  end_integration(s, total, plan);
}

// The integration with the awake list (Sleepers::awake, the awake particles at the start of
// the step, ascending). First the sleepers' wake tests: those the pair loop woke (its lists),
// and in each block of 64 whose sleepers are not all beyond every tool's reach, the sleepers
// near a tool; then, after a barrier, the woken ones are marked and each thread advances an
// equal, contiguous share of the awake list. The same per-particle work as integrate_range over
// every particle: a sleeper far from every tool and woken by no one is not read at all.
void Engine::integrate_listed(State& s, StepTally& total) {
  const int T = threads_;
#pragma omp parallel num_threads(T)
  integrate_listed_thread(s, total, omp_get_thread_num(), T);
  total.sleeping += static_cast<std::int64_t>(s.size() - awake_now_->size());
}

// Thread t's part of integrate_listed (inside a parallel region of T threads; its wake tests
// are a worksharing loop of the region). In one region per step (step_one_region) a thread
// comes here from its boundary contacts: the wake tests read no force, and the loop's barrier
// is where every force of the step is done. Nothing is advanced if a boundary contact overflowed
// (BoundaryContacts::end() throws after the region, as forces() would have before).
void Engine::integrate_listed_thread(State& s, StepTally& total, int t, int T) {
  const std::size_t n = s.size();
  const std::vector<std::int32_t>& A = *awake_now_;
  const std::size_t L = A.size();
  constexpr std::size_t kBlock = Sleepers::kBlock;
  const std::size_t nb = (n + kBlock - 1) / kBlock;
  const std::int32_t S = scene_.sleep.steps;
  const std::int32_t* const REST = s.rest_steps.data();
  const std::uint8_t* const WAKE = sleepers_.wake();
  const Vec3* const X = s.x.data();
  const double* const RAD = s.radius.data();
  cosim::Stopwatch busy;
  StepTally my;
  Sleepers::ThreadNotes notes;
  for (const std::int32_t p : sleepers_.woken(t)) notes.woke.push_back(p);
  // An equal share of the blocks per thread (which thread tests a block changes nothing: the
  // woken are marked after the barrier and counted once each).
  for (std::size_t b = nb * static_cast<std::size_t>(t) / static_cast<std::size_t>(T),
                   b1 = nb * static_cast<std::size_t>(t + 1) / static_cast<std::size_t>(T);
       b < b1; ++b) {
    if (sleepers_.block_far(b)) continue;
    const std::size_t i1 = std::min(n, (b + 1) * kBlock);
    for (std::size_t i = b * kBlock; i < i1; ++i)
      if (REST[i] >= S && !WAKE[i] && sleepers_.near(tools_, X[i], RAD[i]))
        notes.woke.push_back(static_cast<std::int32_t>(i));
  }
  const double tests = busy.seconds();  // the wait at the barrier left out
  // No thread changes rest_steps before every test is made.
  region_barrier(t);
  busy.restart();
  if (boundary_.overflowed()) {
    add_busy(section::integration, t, tests);
    return;
  }
  for (const std::int32_t p : notes.woke) s.rest_steps[static_cast<std::size_t>(p)] = 0;
  integrate_range<true>(s, L * t / T, L * (t + 1) / T, true, false, my, notes, A.data(), t);
  my.sleeping -= static_cast<std::int64_t>(notes.woke.size());
  add_busy(section::integration, t, tests + busy.seconds());
#pragma omp critical(dem_integrate)
  {
    total.merge(my);
    sleepers_.merge(notes, true);
  }
}

// Thread t's part of the integration over particles [a0, a1) (inside a parallel region), its
// tallies merged into total.
template <bool Sleep>
void Engine::integrate_walk_thread(State& s, std::size_t a0, std::size_t a1, bool keep,
                                   bool renote, StepTally& total, int t) {
  const cosim::Stopwatch busy;
  StepTally my;
  Sleepers::ThreadNotes notes;
  integrate_range<Sleep>(s, a0, a1, keep, renote, my, notes, nullptr, t);
  add_busy(section::integration, t, busy.seconds());
#pragma omp critical(dem_integrate)
  {
    total.merge(my);
    if (Sleep) sleepers_.merge(notes, keep);
  }
}

// Particles [a0, a1) of thread t: advanced (the awake ones), their displacements tallied for
// the guard and close pairs, and with Sleep the sleeping rules: a sleeper woken by the pair
// loop or a tool is integrated from the next step on; an awake particle slower than
// scene.sleep.speed for scene.sleep.steps steps, away from every tool, falls asleep.
template <bool Sleep>
void Engine::integrate_range(State& s, std::size_t a0, std::size_t a1, bool keep, bool renote,
                             StepTally& my, Sleepers::ThreadNotes& notes,
                             const std::int32_t* list, int t) {
  const double dt = scene_.dt;
  const double vmax2 = scene_.stability.max_speed * scene_.stability.max_speed;
  const std::int32_t S = scene_.sleep.steps;
  const double rest_speed2 = scene_.sleep.speed * scene_.sleep.speed;
  const FarMoverGuard::Limits limits = FarMoverGuard::limits(scene_);
  const bool close = close_.in_use_for(s);
  const std::uint8_t* const FAST = close ? close_.fast() : nullptr;
  const Vec3* const X_CLOSE = close ? close_.x_at() : nullptr;
  std::vector<std::int32_t>& my_far = guard_.thread_list(static_cast<std::size_t>(t));
  my_far.clear();
  // State's arrays as raw pointers that cannot alias: the compiler keeps their addresses and
  // the running maxima in registers (through State's vectors it reloads them after every
  // store). Both loops below use them.
  const double* __restrict const M = s.mass.data();
  const double* __restrict const RAD = s.radius.data();
  const Vec3* __restrict const FORCE = force_.data();
  const Vec3* __restrict const XR = s.x_at_rebuild.data();
  Vec3* __restrict const V = s.v.data();
  Vec3* __restrict const U = s.u.data();
  Vec3* __restrict const X = s.x.data();
  std::int32_t* __restrict const REST = Sleep ? s.rest_steps.data() : nullptr;
  const std::uint8_t* __restrict const WAKE = Sleep ? sleepers_.wake() : nullptr;
  // The rotating model: its spins (already advanced, Rotation::integrate) count in the rest test,
  // but for their part about gravity's direction (no twisting resistance: a grain on a floor
  // spins about the vertical for ever without moving or pushing anything; docs/dem.md).
  Vec3* const W = Sleep && scene_.rotation.rotating() ? s.w.data() : nullptr;
  Vec3* const WU = W ? s.wu.data() : nullptr;
  const double gn = norm(scene_.gravity);
  const Vec3 gdir = gn > 0 ? (1 / gn) * scene_.gravity : Vec3{};
  if (!Sleep) {
    // All awake (0.88 of the time with the raw pointers than through State's vectors).
    for (std::size_t i = a0; i < a1; ++i) {
      const double v2 = advance(dt, M[i], FORCE[i], V[i], U[i], X[i]);
      if (!(v2 <= vmax2) && my.bad < 0) my.bad = static_cast<std::int64_t>(i);
      const double d2 = norm2(X[i] - XR[i]);
      keep_two_largest(my.d1, my.d2, d2);
      FarMoverGuard::note(my_far, my.far, i, d2, norm2(U[i]), limits);
      if (close && !FAST[i]) {
        keep_two_largest(my.close_d1, my.close_d2, norm2(X[i] - X_CLOSE[i]));
        my.close_u2 = std::max(my.close_u2, norm2(U[i]));
      }
    }
    return;
  }
  auto moved = [&](std::size_t i, double d2) __attribute__((always_inline)) {
    keep_two_largest(my.d1, my.d2, d2);
    FarMoverGuard::note(my_far, my.far, i, d2, norm2(U[i]), limits);
    if (close && !FAST[i]) {  // as in the all-awake loop above
      keep_two_largest(my.close_d1, my.close_d2, norm2(X[i] - X_CLOSE[i]));
      my.close_u2 = std::max(my.close_u2, norm2(U[i]));
    }
  };
  // The sleepers this thread adds to the sleepers' tally (fell asleep this step, or all with
  // renote).
  auto note_sleeper = [&](std::size_t i, double d2) {
    keep_two_largest(notes.d1, notes.d2, d2);
    FarMoverGuard::note(notes.far, notes.tally, i, d2, norm2(U[i]), limits);
  };
  // An awake particle: advanced, tallied, and asleep after scene.sleep.steps slow steps away from
  // every tool. Inlined (as is moved): called per particle, the lambda reloaded every array's
  // address through its captures and kept the next particle's step from starting early (the
  // integration 0.77-0.81x in the main job's DEM; docs/performance.md).
  auto awake_one = [&](std::size_t i) __attribute__((always_inline)) {
    const double v2 = advance(dt, M[i], FORCE[i], V[i], U[i], X[i]);
    if (!(v2 <= vmax2) && my.bad < 0) my.bad = static_cast<std::int64_t>(i);
    const double d2 = norm2(X[i] - XR[i]);
    moved(i, d2);
    std::int32_t r = REST[i];
    double rest2 = v2;  // rotating: (|v| + |w_h| r)^2, w_h the spin's part across gravity
    if (W) {
      const Vec3 wh = W[i] - dot(W[i], gdir) * gdir;
      const double sp = std::sqrt(v2) + std::sqrt(norm2(wh)) * RAD[i];
      rest2 = sp * sp;
    }
    if (rest2 < rest_speed2 && !sleepers_.near(tools_, X[i], RAD[i])) {
      if (++r >= S) {  // falls asleep where it is
        V[i] = U[i] = Vec3{};
        if (W) W[i] = WU[i] = Vec3{};  // and stops turning
        ++my.sleeping;
        notes.fell.push_back(static_cast<std::int32_t>(i));
        if (keep) note_sleeper(i, d2);
      }
    } else {
      r = 0;
    }
    REST[i] = r;
  };
  // The awake list's share [a0, a1) (integrate_listed): every one of them awake.
  if (list) {
    // The awake particles lie among sleepers in memory, a pattern the hardware prefetcher does
    // not follow: the arrays of the particle kAhead entries on are asked for now.
    constexpr std::size_t kAhead = 8;
    for (std::size_t q = a0; q < a1; ++q) {
      if (q + kAhead < a1) {
        const std::size_t p = static_cast<std::size_t>(list[q + kAhead]);
        __builtin_prefetch(&X[p], 1);
        __builtin_prefetch(&V[p], 1);
        __builtin_prefetch(&U[p], 1);
        __builtin_prefetch(&FORCE[p], 0);
        __builtin_prefetch(&XR[p], 0);
        __builtin_prefetch(&M[p], 0);
        __builtin_prefetch(&REST[p], 1);
      }
      awake_one(static_cast<std::size_t>(list[q]));
    }
    return;
  }
  constexpr std::size_t kBlock = Sleepers::kBlock;
  const bool use_blocks = options_.sleeper_blocks;
  bool far_block = false;  // the sleepers of i's block are beyond every tool's reach
  for (std::size_t i = a0; i < a1; ++i) {
    if (keep && (i == a0 || i % kBlock == 0)) {
      far_block = use_blocks && sleepers_.block_far(i / kBlock);
      // A whole block asleep, beyond every tool and woken by no one: nothing to do in it
      // (what the loop below would find particle by particle).
      if (far_block && !renote && i % kBlock == 0 && i + kBlock <= a1) {
        int quiet = 1;
        for (std::size_t q = i; q < i + kBlock; ++q) quiet &= (REST[q] >= S) & (WAKE[q] == 0);
        if (quiet) {
          my.sleeping += static_cast<std::int64_t>(kBlock);
          i += kBlock - 1;
          continue;
        }
      }
    }
    if (REST[i] >= S) {
      // Asleep: not integrated. Woken by the pair loop or a tool, it is integrated from
      // the next step on, with all its forces.
      if (WAKE[i] || (!far_block && sleepers_.near(tools_, X[i], RAD[i]))) {
        REST[i] = 0;
        notes.woke.push_back(static_cast<std::int32_t>(i));
      } else
        ++my.sleeping;
      // It has not moved since it fell asleep (nor this step): already in the tally.
      if (!keep)
        moved(i, norm2(X[i] - XR[i]));
      else if (renote)
        note_sleeper(i, norm2(X[i] - XR[i]));
      continue;
    }
    awake_one(i);
  }
}

// The step after prepare() in one parallel region (EngineOptions::one_region): the same stages,
// the same partition of the work and the same sums as pair_forces, BoundaryContacts::forces and
// integrate, each in its own region, give. What the stages decide before their threads start
// (the pair blocks, the sleepers' rules and awake list, the chunks of the boundary contacts,
// the integration's plan) is made first, by this thread: none of it reads what the threads
// write. In the region: the pair blocks; the boundary chunks (a boundary contact adds to forces
// the pair blocks of another thread wrote: with the awake list a chunk waits for the blocks of
// its particles, wait_for_blocks; else a barrier first); then the integration: with the awake
// list each thread waits for every pair block (the wake tests read the wake flags they set)
// and goes on to its share of the sleepers' wake tests, whose barrier is also the end of every
// force (the wake tests read none), else a barrier and the particles of the blocks the thread
// ran. With the awake list the threads wait for each other at the region's start,
// the one barrier and its end, where the separate regions had three starts, three ends and a
// barrier.
// docs/performance.md, "One parallel region per DEM step".
template <bool Sleep>
void Engine::step_one_region(State& s) {
  const std::size_t n = s.size();
  const int T = threads_;
  cosim::Stopwatch watch;
  force_.resize(n);
  split_pair_work(s);
  detail::PairSleep rules;
  awake_now_ = nullptr;
  if (Sleep) {
    rules = sleepers_.pair_rules(s, options_.sleeper_row_skip);
    if (options_.awake_list) awake_now_ = &sleepers_.awake(s);
  }
  const BlockPass pass = begin_pair_blocks(s, pair_rows_of(s), rules);
  timing_.lap(section::pair_forces, watch);
  const bool boundary = boundary_.begin(s);
  const std::uint8_t* const ghost = ghost_ ? ghost_->data() : nullptr;
  timing_.lap(section::mesh_contacts, watch);
  const IntegrationPlan plan = begin_integration<Sleep>(s);
  timing_.lap(section::integration, watch);
  StepTally total;
  // With the awake list a thread goes from its pair blocks to the boundary chunks without a
  // barrier: before a chunk it waits for the pair blocks that write its particles' forces.
  BoundaryContacts::ChunkWait chunk_wait;
  chunk_wait.fn = &Engine::wait_for_blocks;
  chunk_wait.ctx = &pass;
  const BoundaryContacts::ChunkWait* const wait = plan.listed ? &chunk_wait : nullptr;
  // The sections' wall times inside the region, from its start: the pair blocks end when the
  // last thread leaves its walk, the boundary contacts when the last thread leaves its chunks.
  // With the awake list the two overlap (a thread runs chunks while another still runs pair
  // blocks): the region's wall time is then shared among the three sections in proportion to
  // the threads' working seconds in each (thread_busy, waits left out) in this step.
  region_marks_.assign(2 * static_cast<std::size_t>(T), 0.0);
  double busy_before[3] = {0, 0, 0};
  const std::size_t sections[3] = {section::pair_forces, section::mesh_contacts,
                                   section::integration};
  for (int q = 0; q < 3; ++q)
    for (int u = 0; u < T; ++u) busy_before[q] += thread_busy(sections[q], u);
  auto body = [&](int t) {
    pair_blocks_thread<Sleep>(s, pass, t, T);
    region_marks_[static_cast<std::size_t>(T + t)] = watch.seconds();
    if (!wait) region_barrier(t);
    if (boundary)
      boundary_.run(s, tools_, force_.data(), t, T, busy_row(section::mesh_contacts), nullptr,
                    ghost, wait);
    region_marks_[static_cast<std::size_t>(t)] = watch.seconds();
    if (plan.listed) {
      // The wake tests read the wake flags the pair blocks set: every block done first.
      if (n > 0) wait_for_blocks(&pass, 0, n - 1);
      integrate_listed_thread(s, total, t, T);
    } else {
      std::size_t split[2];
      owner_range(pass, T, t, split);
      region_barrier(t);
      if (!boundary_.overflowed())
        integrate_walk_thread<Sleep>(s, split[0], split[1], plan.keep, plan.renote, total, t);
    }
  };
  if (scene_.thread_wait == ThreadWait::yield && T > 1) {
    if (!team_ || team_->size() != T) {
      // Each worker on the CPUs libgomp gives OpenMP's thread of its number (OMP_PROC_BIND).
      std::vector<std::vector<int>> cpus;
      for (const ThreadCpus& c : thread_cpus(T)) cpus.push_back(c.allowed);
      team_ = std::make_unique<ThreadTeam>(T, cpus);
    }
    region_team_ = team_.get();
    struct Reset {
      ThreadTeam*& team;
      ~Reset() { team = nullptr; }
    } reset{region_team_};
    team_->run(body);
  } else {
#pragma omp parallel num_threads(T)
    body(omp_get_thread_num());
  }
  const double region = watch.lap();
  double work[3] = {0, 0, 0}, all = 0;
  for (int q = 0; q < 3; ++q) {
    for (int u = 0; u < T; ++u) work[q] += thread_busy(sections[q], u);
    work[q] = std::max(0.0, work[q] - busy_before[q]);
    all += work[q];
  }
  if (wait && all > 0) {
    for (int q = 0; q < 3; ++q) timing_.add(sections[q], region * work[q] / all);
  } else {
    const double pair_end = *std::max_element(region_marks_.begin() + T, region_marks_.end());
    const double mesh_end =
        std::max(pair_end, *std::max_element(region_marks_.begin(), region_marks_.begin() + T));
    timing_.add(section::pair_forces, pair_end);
    timing_.add(section::mesh_contacts, mesh_end - pair_end);
    timing_.add(section::integration, region - mesh_end);
  }
  split_.resize(static_cast<std::size_t>(T) + 1);
  owner_split(pass, T, split_.data());
  if (boundary) boundary_.end(s);  // throws if a particle had too many boundary contacts
  sum_contact_stats();
  timing_.lap(section::mesh_contacts, watch);
  if (plan.listed) total.sleeping += static_cast<std::int64_t>(n - awake_now_->size());
  end_integration(s, total, plan);
  ++one_region_steps_;
  timing_.lap(section::integration, watch);
}

// After the threads: the state's displacements for the guard, the close pairs' tally, the step
// counted, the sleepers' counters and the far movers of the new state; a blow-up stops the run.
void Engine::finish_step(State& s, const StepTally& total, int lists, bool close) {
  const int T = threads_;
  s.max_displacement = std::sqrt(total.d1);
  s.second_displacement = std::sqrt(total.d2);
  if (close) close_.set_tally(total.close_d1, total.close_d2, total.close_u2);
  ++s.step;
  close_.stepped(s);  // its copies of the springs are of this state
  if (scene_.sleep.enabled)
    sleepers_.stepped(s, total.sleeping);
  else
    sleepers_.set_sleeping(total.sleeping);
  ++s.steps_since_rebuild;
  // The far movers of the new state (ascending and each once: a woken sleeper may be in both
  // the threads' lists and the sleepers').
  guard_.finish(s, lists, total.far, lists > T);
  if (total.bad >= 0) {
    const std::size_t i = static_cast<std::size_t>(total.bad);
    const double dt = scene_.dt;
    std::ostringstream msg;
    msg << "blow-up at step " << s.step << " (t = " << s.step * dt << " s): particle id "
        << s.id[i] << " at (" << s.x[i].x << ", " << s.x[i].y << ", " << s.x[i].z
        << ") has speed " << norm(s.v[i]) << " m/s (limit scene.stability.max_speed = "
        << scene_.stability.max_speed << "); kinetic energy " << kinetic_energy(s)
        << " J. Lower scene.dt (now " << dt << ", largest safe " << largest_safe_dt(scene_)
        << ") or soften contact normal_stiffness";
    throw SimulationError(msg.str());
  }
}

// --- Diagnostics.

std::vector<std::pair<std::int64_t, std::int64_t>> Engine::particle_contacts(
    const State& s) const {
  std::vector<std::pair<std::int64_t, std::int64_t>> out;
  for (std::size_t i = 0; i + 1 < s.pair_offset.size(); ++i)
    for (std::int32_t k = s.pair_offset[i]; k < s.pair_offset[i + 1]; ++k) {
      const std::int32_t j = s.pair_j[k];
      const double rsum = s.radius[i] + s.radius[j];
      if (norm2(s.x[i] - s.x[j]) < rsum * rsum)
        out.emplace_back(std::min(s.id[i], s.id[j]), std::max(s.id[i], s.id[j]));
    }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<Engine::MeshContact> Engine::mesh_contacts(const State& s) {
  tools_.update(scene_, s);
  return boundary_.mesh_contacts(s, tools_);
}

std::size_t Engine::workspace_bytes() const {
  std::size_t b = broad_.workspace_bytes() + force_.capacity() * sizeof(Vec3) + sleepers_.bytes() +
                  tools_.bytes() + close_.bytes() + blocks_.bytes() + boundary_.bytes() +
                  rotation_.bytes() +
                  split_.capacity() * sizeof(std::size_t);
  for (const auto& v : remote_) b += v.capacity() * sizeof(detail::PairRemote);
  return b;
}

std::string close_pairs_summary(const Engine& engine, long long steps) {
  if (!close_pairs_on(engine.scene(), engine.options())) return {};
  char line[200];
  std::snprintf(line, sizeof line,
                "Close pairs: listed %lld times in %lld steps; the last listing kept %.1f %% of "
                "the candidates%s",
                static_cast<long long>(engine.close_builds()), steps, 100 * engine.close_share(),
                engine.close_builds() == 0 || engine.close_used()
                    ? ""
                    : " (over 90 %: every candidate read instead)");
  return line;
}

std::string sleeping_summary(const Engine& engine, double asleep_share, long long steps) {
  if (!engine.scene().sleep.enabled) return {};
  const double per = steps > 0 ? 1.0 / static_cast<double>(steps) : 0.0;
  char line[240];
  std::snprintf(line, sizeof line,
                "Sleeping: %.1f %% of particle-steps asleep, %lld asleep at the end; woke %lld, "
                "fell asleep %lld (%.3g and %.3g per step)",
                100 * asleep_share, static_cast<long long>(engine.sleeping()),
                static_cast<long long>(engine.woke_total()),
                static_cast<long long>(engine.fell_asleep_total()),
                static_cast<double>(engine.woke_total()) * per,
                static_cast<double>(engine.fell_asleep_total()) * per);
  return line;
}

double payload_mass(const State& s, const Mesh& mesh, const ToolPose& pose) {
  if (mesh.vertices.empty()) return 0;
  Vec3 lo = mesh.vertices[0], hi = mesh.vertices[0];
  for (const Vec3& v : mesh.vertices) {
    lo = {std::min(lo.x, v.x), std::min(lo.y, v.y), std::min(lo.z, v.z)};
    hi = {std::max(hi.x, v.x), std::max(hi.y, v.y), std::max(hi.z, v.z)};
  }
  const Mat3 R = to_matrix(pose.orientation);  // tool frame -> ground
  double mass = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const Vec3 l = to_frame(R, s.x[i] - pose.position);  // the centre in the tool frame
    if (l.x >= lo.x && l.x <= hi.x && l.y >= lo.y && l.y <= hi.y && l.z >= lo.z && l.z <= hi.z)
      mass += s.mass[i];
  }
  return mass;
}

double kinetic_energy(const State& s) {
  double e = 0;
  for (std::size_t i = 0; i < s.size(); ++i) e += 0.5 * s.mass[i] * norm2(s.v[i]);
  if (!s.w.empty()) e += rotational_energy(s);  // the rotating model's spins
  return e;
}

}  // namespace dem
