// Close pairs (EngineOptions::close_margin): the candidates of the half list within `margin`
// (close_distance(), close_margin * r_max) of contact, and every candidate of a particle faster than `fast` when
// they were listed. A pair left out was farther apart than the margin, so it cannot act (or hold
// history) before the slow particles' two largest displacements since then and their step
// window add up to the margin (checked before each step's pair forces, tallied by the
// integration). The results are the same bits as with every candidate.
#pragma once

#include <cstdint>
#include <vector>

#include "dem/list_stamp.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem {

class ClosePairs {
 public:
  // Whether the listing still holds for s: made from its lists at this step, and the slow
  // particles cannot have closed the margin since.
  bool hold(const Scene& scene, double margin, const State& s) const;
  // Lists them from s's half list, with the threads' row ranges `bounds` (T + 1 entries).
  // Clears the springs of the pairs left out (farther apart than the margin).
  void list(const Scene& scene, double margin, State& s, const std::vector<std::size_t>& bounds,
            int T);

  // false: they kept nearly every candidate, the half list is read instead.
  bool use() const { return use_; }
  // Their rows (CSR), partners, the pair's index in the half list, and copies of the springs.
  const std::int32_t* offset() const { return offset_.data(); }
  const std::int32_t* partner() const { return partner_.data(); }
  const std::int32_t* index() const { return index_.data(); }
  Vec3* spring() { return spring_.data(); }

  // For the integration: in use for s (listed from it, same size); per particle whether it
  // was fast when listed, and its position then.
  bool in_use_for(const State& s) const {
    return use_ && stamp_.matches(s, ListStamp::state | ListStamp::size);
  }
  const std::uint8_t* fast() const { return fast_.data(); }
  const Vec3* x_at() const { return x_at_.data(); }
  // The slow particles since the listing: two largest squared displacements, largest speed^2.
  void set_tally(double d1, double d2, double u2) {
    d1_ = d1;
    d2_ = d2;
    u2_ = u2;
  }
  // After a step of s: the copies of the springs are of its new step.
  void stepped(const State& s) {
    if (stamp_.of(s)) stamp_.set_step(s.step);
  }

  std::int64_t builds() const { return builds_; }
  double share() const { return share_; }  // of the candidates, kept by the last listing
  std::size_t bytes() const;

 private:
  std::vector<std::int32_t> offset_, partner_, index_;  // CSR rows; index: the pair in the half list
  std::vector<Vec3> spring_;  // copies of their springs, in their order (both are written)
  std::vector<std::uint8_t> keep_, fast_;  // per candidate; per particle
  std::vector<Vec3> x_at_;                 // positions when listed
  std::vector<std::int64_t> thread_base_;
  ListStamp stamp_;  // the lists they were taken from, and the step the copies are of
  double d1_ = 0, d2_ = 0, u2_ = 0;
  bool use_ = false;
  std::int64_t builds_ = 0;
  double share_ = 0;
};

}  // namespace dem
