#include "dem/close_pairs.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>

namespace dem {
namespace {

// A particle is fast, and keeps all its candidates listed, above the speed that would close
// the margin within kCloseSteps steps together with another (2 v dt kCloseSteps = margin).
// In the paper's pile (margin 4 mm, dt 1e-4 s: 0.05 m/s) 25 steps listed every 17 steps and
// kept 68 % of the candidates; 400 lists about every 40 steps, keeping 71 %.
constexpr double kCloseSteps = 400;
// The margin the check allows: a little below the listed one (the rounding of the distances).
constexpr double kCloseSlack = 0.999;
// Above this share of the candidates kept (a gas, or most particles fast), the half list is
// read: the copies cost more than the few pairs they spare.
constexpr double kCloseMaxShare = 0.9;

}  // namespace

bool ClosePairs::hold(const Scene& scene, double margin, const State& s) const {
  // New lists, another state, or a state put back (a repeated macro step): not these.
  if (!stamp_.matches(s, ListStamp::lists | ListStamp::step)) return false;
  if (!use_) return true;  // the half list is read until its next build
  return std::sqrt(d1_) + std::sqrt(d2_) + scene.dt * std::sqrt(u2_) <=
         kCloseSlack * margin;
}

void ClosePairs::list(const Scene& scene, double margin, State& s,
                      const std::vector<std::size_t>& bounds, int T) {
  const std::size_t n = s.size();
  const double fast = margin / (2 * kCloseSteps * scene.dt);
  const double fast2 = fast * fast;
  offset_.resize(n + 1);
  fast_.resize(n);
  x_at_.resize(n);
  keep_.resize(s.pair_j.size());
  thread_base_.assign(T + 1, 0);
  double slow_u2 = 0;
  const Vec3* const X = s.x.data();
  const Vec3* const U = s.u.data();
  const double* const R = s.radius.data();
  const std::int32_t* const off = s.pair_offset.data();
  const std::int32_t* const J = s.pair_j.data();
  Vec3* const spring = s.pair_spring.data();
  // Sleeping: two sleepers keep their spring while both sleep (the pair loop skips them), so a
  // pair of two sleepers that holds one stays listed (they do not move: it cannot have come
  // apart beyond the margin, but nothing here relies on that).
  const bool sleep = scene.sleep.enabled && s.rest_steps.size() == n;
  const std::int32_t* const REST = sleep ? s.rest_steps.data() : nullptr;
  const std::int32_t S = scene.sleep.steps;
#pragma omp parallel num_threads(T) reduction(max : slow_u2)
  {
    const int t = omp_get_thread_num();
    const std::size_t a0 = bounds[t], a1 = bounds[t + 1];
    for (std::size_t i = a0; i < a1; ++i) {
      const double u2 = norm2(U[i]);
      fast_[i] = u2 > fast2;
      if (!fast_[i]) slow_u2 = std::max(slow_u2, u2);
      x_at_[i] = X[i];
    }
#pragma omp barrier
    std::int64_t kept = 0;
    for (std::size_t i = a0; i < a1; ++i) {
      const Vec3 xi = X[i];
      const double ri = R[i];
      const bool fi = fast_[i];
      for (std::int32_t k = off[i]; k < off[i + 1]; ++k) {
        const std::int32_t j = J[k];
        const double reach = ri + R[j] + margin;
        const bool keep = fi || fast_[j] || norm2(xi - X[j]) < reach * reach ||
                          (sleep && REST[i] >= S && REST[j] >= S && nonzero(spring[k]));
        keep_[k] = keep;
        kept += keep;
        // Farther apart than the margin: out of contact this step, so the pair loop would
        // clear its history now; it is cleared here.
        if (!keep && nonzero(spring[k])) spring[k] = Vec3{};
      }
    }
    thread_base_[t + 1] = kept;
#pragma omp barrier
#pragma omp single
    for (int q = 0; q < T; ++q) thread_base_[q + 1] += thread_base_[q];
    // (the single's barrier)
#pragma omp single nowait
    {
      partner_.resize(static_cast<std::size_t>(thread_base_[T]));
      index_.resize(static_cast<std::size_t>(thread_base_[T]));
      spring_.resize(static_cast<std::size_t>(thread_base_[T]));
    }
#pragma omp barrier
    std::int32_t q = static_cast<std::int32_t>(thread_base_[t]);
    for (std::size_t i = a0; i < a1; ++i) {
      offset_[i] = q;
      for (std::int32_t k = off[i]; k < off[i + 1]; ++k)
        if (keep_[k]) {
          partner_[q] = J[k];
          index_[q] = k;
          spring_[q] = spring[k];
          ++q;
        }
    }
  }
  offset_[n] = static_cast<std::int32_t>(thread_base_[T]);
  stamp_.take(s);
  d1_ = d2_ = 0;
  u2_ = slow_u2;
  const std::size_t candidates = s.pair_j.size();
  share_ = candidates ? static_cast<double>(thread_base_[T]) / candidates : 0;
  use_ = share_ <= kCloseMaxShare;
  ++builds_;
}

std::size_t ClosePairs::bytes() const {
  return (offset_.capacity() + partner_.capacity() + index_.capacity()) * sizeof(std::int32_t) +
         (spring_.capacity() + x_at_.capacity()) * sizeof(Vec3) + keep_.capacity() +
         fast_.capacity() + thread_base_.capacity() * sizeof(std::int64_t);
}

}  // namespace dem
