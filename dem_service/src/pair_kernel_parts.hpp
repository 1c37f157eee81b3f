// What the scalar pair loop and the chunk kernel (real and emulated) share: the wakes, the
// partner's share of a pair force, the statistics. Private to the pair kernel's sources.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "dem/pair_kernel.hpp"

namespace dem::detail {
namespace {

// Wakes sleeper p: directly in this thread's range (and noted in the thread's list of woken
// sleepers the first time), queued otherwise (the partner j > i of a pair in this range is never
// in an earlier thread's range).
inline void wake(const PairSleep& sl, std::size_t p, std::size_t a1) {
  if (p < a1) {
    if (!sl.wake[p] && sl.woken) sl.woken->push_back(static_cast<std::int32_t>(p));
    sl.wake[p] = 1;
  } else
    sl.remote_wake->push_back(static_cast<std::int32_t>(p));
}

// The partner's share of a pair force: subtracted directly in this thread's range, handed on
// (in pair order) beyond it.
inline void on_partner(Vec3* F, std::vector<PairRemote>& remote, std::int32_t j, Vec3 f,
                       std::size_t a1) {
  if (static_cast<std::size_t>(j) < a1)
    F[j] -= f;
  else
    remote.push_back({j, f});
}

inline void add_stats(PairRowStats& stats, std::int64_t contacts, double max_overlap,
                      double max_overlap_ratio) {
  stats.contacts += contacts;
  stats.max_overlap = std::max(stats.max_overlap, max_overlap);
  stats.max_overlap_ratio = std::max(stats.max_overlap_ratio, max_overlap_ratio);
}

}  // namespace

// The chunk kernel with its lanes emulated in portable code (pair_kernel_emulated.cpp); sleep:
// the sleeping rules, or nullptr for all awake.
void pair_rows_emulated(const PairRows& p, const PairSleep* sleep, std::size_t a0, std::size_t a1,
                        std::size_t direct, std::vector<PairRemote>& remote, PairRowStats& stats);
// On AVX2 lanes (pair_kernel_avx2.cpp); sleep: the sleeping rules, or nullptr for all awake.
// Only where pair_rows_avx2_available().
void pair_rows_avx2(const PairRows& p, const PairSleep* sleep, std::size_t a0, std::size_t a1,
                    std::size_t direct, std::vector<PairRemote>& remote, PairRowStats& stats);
// The scalar loop, all awake or with the sleeping rules (pair_kernel.cpp): pair_rows_avx2 runs a
// row longer than its queue through it.
void pair_rows_scalar_awake(const PairRows& p, std::size_t a0, std::size_t a1, std::size_t direct,
                            std::vector<PairRemote>& remote, PairRowStats& stats);
void pair_rows_scalar_sleep(const PairRows& p, const PairSleep& sleep, std::size_t a0,
                            std::size_t a1, std::size_t direct, std::vector<PairRemote>& remote,
                            PairRowStats& stats);

}  // namespace dem::detail
