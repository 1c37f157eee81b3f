#include "dem/pair_blocks.hpp"

#include <algorithm>

namespace dem {
namespace {

// About kPairBlocks blocks, none shorter than kPairBlockMin rows. Block k + 2 starts after the
// last partner of block k, so block k's partners lie in blocks k and k + 1.
constexpr std::size_t kPairBlocks = 64;
constexpr std::size_t kPairBlockMin = 512;

}  // namespace

void PairBlocks::make(const State& s) {
  const std::size_t n = s.size();
  if (stamp_.matches(s, ListStamp::lists)) return;
  const std::int32_t* const off = s.pair_offset.data();
  const std::int32_t* const J = s.pair_j.data();
  const std::size_t target = std::max(kPairBlockMin, n / kPairBlocks);
  start_.assign(1, 0);
  if (n > 0) start_.push_back(std::min(n, target));
  while (start_.back() < n) {
    const std::size_t k0 = start_[start_.size() - 2], k1 = start_.back();
    std::size_t reach = k1;  // one past the last partner of block [k0, k1)
    for (std::int32_t q = off[k0]; q < off[k1]; ++q)
      reach = std::max(reach, static_cast<std::size_t>(J[q]) + 1);
    start_.push_back(std::min(n, std::max(k1 + target, reach)));
  }
  const std::size_t K = start_.size() - 1;
  done_.assign(K, 0);
  claim_.assign(K, 0);
  owner_.assign(K, 0);
  pass_ = 0;
  stamp_.take(s);
}

std::size_t PairBlocks::bytes() const {
  return start_.capacity() * sizeof(std::size_t) +
         (done_.capacity() + claim_.capacity()) * sizeof(std::int64_t) +
         owner_.capacity() * sizeof(int);
}

namespace detail {

std::vector<std::int32_t> pair_block_walk(std::int32_t K, int t, int T) {
  std::vector<std::int32_t> w;
  if (K <= 0) return w;
  w.reserve(K);
  if (T >= 2 && t == T - 1) {
    // Backward from the top: E_L (L the last even), O_{K-1} if K - 1 is odd, then each even
    // followed by the odd block above it.
    const std::int32_t L = (K - 1) / 2 * 2;
    w.push_back(L);
    if (L + 1 < K) w.push_back(L + 1);
    for (std::int32_t e = L - 2; e >= 0; e -= 2) {
      w.push_back(e);
      w.push_back(e + 1);
    }
    return w;
  }
  // Forward over [a, b) (a even): each even, then the odd block below it; the odd block below
  // b last (its upper neighbour, b, was walked first or does not exist).
  auto forward = [&w](std::int32_t a, std::int32_t b) {
    for (std::int32_t e = a; e < b; e += 2) {
      w.push_back(e);
      if (e > a) w.push_back(e - 1);
    }
    const std::int32_t last_even = a + (b - 1 - a) / 2 * 2;
    if (last_even + 1 < b) w.push_back(last_even + 1);
  };
  const std::int32_t s = static_cast<std::int32_t>(static_cast<std::int64_t>(K) * t / T) / 2 * 2;
  forward(s, K);
  if (s > 0) forward(0, s);
  return w;
}

}  // namespace detail

}  // namespace dem
