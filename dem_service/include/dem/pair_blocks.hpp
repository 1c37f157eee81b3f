// Pair blocks (EngineOptions::pair_schedule blocks): consecutive row ranges of the half list, every
// partner of block k's rows in block k or k + 1, made from the lists at each broad phase. An
// even block sets up its own and the next block's forces and runs its rows; an odd block runs
// once the two even blocks beside it are done. Each thread walks all blocks in its own order
// (detail::pair_block_walk) and runs those it claims first, so a thread keeps the same part of
// the bed from step to step and a slowed thread runs fewer blocks. The blocks are a function of
// the lists alone, never of the thread count, so the sums are the same on any number of threads.
#pragma once

#include <cstdint>
#include <vector>

#include "dem/list_stamp.hpp"
#include "dem/state.hpp"

namespace dem {

class PairBlocks {
 public:
  // Makes the blocks for s's lists unless they are made already.
  void make(const State& s);
  // A new pass over the blocks (one step's pair forces): its number.
  std::int64_t next_pass() { return ++pass_; }

  std::int64_t count() const { return static_cast<std::int64_t>(start_.size()) - 1;  }
  // The first row of each block and the end (K + 1 entries).
  const std::vector<std::size_t>& start() const { return start_; }
  std::int64_t* done() { return done_.data(); }    // the pass in which block k's rows were done
  std::int64_t* claim() { return claim_.data(); }  // the pass in which block k was claimed
  std::vector<int>& owner() { return owner_; }     // the thread that ran block k in the last pass
  std::size_t bytes() const;

 private:
  std::vector<std::size_t> start_;
  std::vector<std::int64_t> done_, claim_;
  std::vector<int> owner_;
  std::int64_t pass_ = 0;
  ListStamp stamp_;  // the lists they were made for
};

// True for the first thread to claim task k in this pass (pair blocks, boundary chunks): a
// relaxed look first, so a task already taken costs no exchange.
inline bool claim_first(std::int64_t* claim, std::size_t k, std::int64_t pass) {
  return __atomic_load_n(&claim[k], __ATOMIC_RELAXED) != pass &&
         __atomic_exchange_n(&claim[k], pass, __ATOMIC_ACQ_REL) != pass;
}

namespace detail {
// The order in which thread t of T visits K pair blocks (and the boundary chunks): every block
// once, an even block before the odd blocks beside it. Threads 0 .. T-2 walk forward from the
// (even) block near t K / T, wrapping round to block 0; the last thread (T >= 2) walks backward
// from block K - 1. On two threads one walks up from the bottom of the bed and the other down
// from its top.
std::vector<std::int32_t> pair_block_walk(std::int32_t K, int t, int T);
}  // namespace detail

}  // namespace dem
