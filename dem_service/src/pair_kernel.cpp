#include "dem/pair_kernel.hpp"

#include "pair_kernel_parts.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace dem::detail {

namespace {

template <bool Sleep>
void pair_rows_scalar(const PairRows& p, const PairSleep& sl, std::size_t a0, std::size_t a1,
                      std::size_t direct, std::vector<PairRemote>& remote, PairRowStats& stats) {
  const ContactLaw law = p.law;  // a local copy: no reloads after stores
  const double dt = p.dt;
  const Vec3* const X = p.x;
  const Vec3* const U = p.u;
  const double* const R = p.radius;
  const double* const M = p.mass;
  const std::int32_t* const off = p.offset;
  const std::int32_t* const J = p.partner;
  Vec3* const spring = p.spring;
  const std::int32_t* const SI = p.spring_index;  // close pairs: their springs' homes
  Vec3* const HOME = p.spring_home;
  Vec3* const F = p.force;
  const std::int32_t* const REST = sl.rest;
  const std::int32_t S = sl.steps;
  std::int64_t contacts = 0;
  double max_overlap = 0, max_overlap_ratio = 0;
  ContactCoefficients c;
  double last_ri = -1, last_mi = -1, last_rj = -1, last_mj = -1;
  for (std::size_t i = a0; i < a1; ++i) {
    const Vec3 xi = X[i], ui = U[i];
    const double ri = R[i], mi = M[i];
    if (ri != last_ri || mi != last_mi) {
      last_ri = ri;
      last_mi = mi;
      last_rj = last_mj = -1;
    }
    const bool si = Sleep && REST[i] >= S;
    // A sleeper with only sleepers in its row: nothing to compute (the loop below would skip
    // every pair), so its row is not read at all.
    if (Sleep && si && sl.awake_partners && sl.awake_partners[i] == 0) continue;
    Vec3 fi{};
    for (std::int32_t k = off[i]; k < off[i + 1]; ++k) {
      const std::int32_t j = J[k];
      Vec3& sk = spring[k];
      bool sj = false;
      if (Sleep) {
        sj = REST[j] >= S;
        if (si && sj) continue;  // two sleepers: no force, the spring stays as it was
      }
      const Vec3 d = xi - X[j];
      const double rsum = ri + R[j];
      const double d2 = norm2(d);
      const Vec3 urel = ui - U[j];
      if (d2 >= rsum * rsum && surely_apart(d2, rsum, norm2(urel), dt)) {
        // Contact ended: history is forgotten (write only if there is something to clear).
        if (nonzero(sk)) {
          // A sleeper whose contact with an awake particle ends may have lost its support.
          if (Sleep && (si || sj)) wake(sl, si ? i : static_cast<std::size_t>(j), direct);
          sk = Vec3{};
          if (SI) HOME[SI[k]] = sk;
        }
        continue;
      }
      const double dist = std::sqrt(d2);
      const Vec3 nrm = dist > 0 ? (1.0 / dist) * d : Vec3{0, 0, 1};
      const double rj = R[j], mj = M[j];
      // Monodisperse beds repeat the same pair: reuse the coefficients (saves a sqrt).
      if (rj != last_rj || mj != last_mj) {
        c = coefficients(law, ri * rj / rsum, mi * mj / (mi + mj));
        last_rj = rj;
        last_mj = mj;
      }
      Vec3 f;
      const bool acts = contact_force(law, c, rsum - dist, nrm, urel, sk, dt, f);
      if (!acts) sk = Vec3{};
      if (SI) HOME[SI[k]] = sk;
      if (!acts) continue;
      ++contacts;
      max_overlap = std::max(max_overlap, rsum - dist);
      max_overlap_ratio = std::max(max_overlap_ratio, (rsum - dist) / std::min(ri, rj));
      // Awake against asleep: the force acts on the awake particle only; a partner moving
      // faster than scene.sleep.wake_speed (by default speed) relative to the sleeper wakes it.
      if (Sleep && (si || sj) && norm2(urel) > sl.wake_speed2)
        wake(sl, si ? i : static_cast<std::size_t>(j), direct);
      if (!Sleep || !si) fi += f;
      if (!Sleep || !sj) on_partner(F, remote, j, f, direct);
    }
    F[i] += fi;
  }
  add_stats(stats, contacts, max_overlap, max_overlap_ratio);
}

#if defined(__x86_64__) && defined(__GNUC__)
#define DEM_AVX512 __attribute__((target("avx512f,avx512vl,avx512dq")))
#include "pair_kernel_chunks.inc"
#undef DEM_AVX512
#endif

}  // namespace

void pair_rows_scalar_awake(const PairRows& p, std::size_t a0, std::size_t a1, std::size_t direct,
                            std::vector<PairRemote>& remote, PairRowStats& stats) {
  pair_rows_scalar<false>(p, PairSleep{}, a0, a1, direct, remote, stats);
}

void pair_rows_scalar_sleep(const PairRows& p, const PairSleep& sleep, std::size_t a0,
                            std::size_t a1, std::size_t direct, std::vector<PairRemote>& remote,
                            PairRowStats& stats) {
  pair_rows_scalar<true>(p, sleep, a0, a1, direct, remote, stats);
}

bool pair_rows_vector_available() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
         __builtin_cpu_supports("avx512dq");
#else
  return false;
#endif
}

static bool branch_free_by_processor() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_is("amd");
#else
  return false;
#endif
}

bool branch_free_chunks_default() {
  static const bool by_processor = branch_free_by_processor();
  return by_processor;
}

// The one place that picks the kernel: the vector one when asked for and available, the
// emulated one when asked for, the AVX2 one when asked for (or for the vector one where AVX-512
// is missing) and available, else the scalar loop.
template <bool Sleep>
static void dispatch(const PairRows& p, const PairSleep& sleep, std::size_t a0, std::size_t a1,
                     std::vector<PairRemote>& remote, PairRowStats& stats, Kernel kernel) {
  // Partners below `direct` are written directly (PairRows::direct_end; 0: the rows' end).
  const std::size_t direct = p.direct_end ? std::max(p.direct_end, a1) : a1;
  if (kernel == Kernel::emulated) {
    pair_rows_emulated(p, Sleep ? &sleep : nullptr, a0, a1, direct, remote, stats);
    return;
  }
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool available = pair_rows_vector_available();
  if (kernel == Kernel::vector && available) {
    run_chunk_kernel<Sleep>(p, sleep, a0, a1, direct, remote, stats);
    return;
  }
#endif
  // Without AVX-512: 4 pairs at a time on AVX2 where the processor has it.
  static const bool avx2 = pair_rows_avx2_available();
  if ((kernel == Kernel::vector || kernel == Kernel::avx2) && avx2) {
    pair_rows_avx2(p, Sleep ? &sleep : nullptr, a0, a1, direct, remote, stats);
    return;
  }
  pair_rows_scalar<Sleep>(p, sleep, a0, a1, direct, remote, stats);
}

void pair_rows(const PairRows& p, std::size_t a0, std::size_t a1, std::vector<PairRemote>& remote,
               PairRowStats& stats, Kernel kernel) {
  dispatch<false>(p, PairSleep{}, a0, a1, remote, stats, kernel);
}

void pair_rows_sleep(const PairRows& p, const PairSleep& sleep, std::size_t a0, std::size_t a1,
                     std::vector<PairRemote>& remote, PairRowStats& stats, Kernel kernel) {
  dispatch<true>(p, sleep, a0, a1, remote, stats, kernel);
}

}  // namespace dem::detail
