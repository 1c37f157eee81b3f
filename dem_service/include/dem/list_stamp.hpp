// Which state, lists and step a piece of the engine's workspace was made for. The engine keeps
// lists beside State (close pairs, pair blocks, awake partners per row, the sleepers' tally, the
// far movers); each is valid only for the state it was made from, with the same particles and
// lists, and some only at the same step. A caller that steps a copy, puts a state back (a
// repeated macro step) or rebuilds by hand gets them made again instead of stale ones.
#pragma once

#include <cstddef>
#include <cstdint>

#include "dem/state.hpp"

namespace dem {

class ListStamp {
 public:
  // What a check compares (or-ed): the state object, its particle count, its candidate count,
  // its broad-phase count, the step of its last broad phase, and the step itself.
  enum Field : unsigned {
    state = 1u,
    size = 2u,
    candidates = 4u,
    rebuilds = 8u,
    built_at = 16u,
    step = 32u,
    lists = state | size | candidates | rebuilds | built_at,  // the lists of this broad phase
  };

  // Made for s as it is now; `at_step` is the step it is valid at (s.step unless a caller
  // stamps for the step being finished).
  void take(const State& s) { take(s, s.step); }
  void take(const State& s, std::int64_t at_step) {
    state_ = &s;
    size_ = s.size();
    candidates_ = s.pair_j.size();
    rebuilds_ = s.rebuilds;
    built_at_ = s.step - s.steps_since_rebuild;
    step_ = at_step;
  }
  // Moves the stamp on to another step of the same lists (the workspace was kept up to date).
  void set_step(std::int64_t at_step) { step_ = at_step; }
  void clear() { state_ = nullptr; }

  // True when every field in `fields` matches s (the step against `at_step`).
  bool matches(const State& s, unsigned fields) const { return matches(s, fields, s.step); }
  bool matches(const State& s, unsigned fields, std::int64_t at_step) const {
    if ((fields & state) && state_ != &s) return false;
    if ((fields & size) && size_ != s.size()) return false;
    if ((fields & candidates) && candidates_ != s.pair_j.size()) return false;
    if ((fields & rebuilds) && rebuilds_ != s.rebuilds) return false;
    if ((fields & built_at) && built_at_ != s.step - s.steps_since_rebuild) return false;
    if ((fields & step) && step_ != at_step) return false;
    return true;
  }
  bool of(const State& s) const { return state_ == &s; }  // made from this state object
  std::int64_t rebuilds_seen() const { return rebuilds_; }

 private:
  const State* state_ = nullptr;
  std::size_t size_ = 0, candidates_ = 0;
  std::int64_t rebuilds_ = -1, built_at_ = -1, step_ = -1;
};

}  // namespace dem
