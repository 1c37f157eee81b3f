// Sleeping particles and the region of interest (Scene::sleep, Scene::region; docs/dem.md
// "Sleeping and the region of interest"): what the engine keeps about the sleepers between
// steps, and the sleeping rules its stages apply.
//
// * The pair loop's rules (pair_rules()): wake flags, the awake partners of each row so that a
//   sleeper's row is read only when it holds one (AwakePartners), and queued remote wakes.
// * The integration's rules: each tool's neighbourhood this step (near(), block_far()), and the
//   sleepers' share of the guard's tallies (the two largest displacements, the far movers):
//   a sleeper does not move, so it is noted once, when it falls asleep (the tally), instead of
//   every step.
// * The region of interest: particles whose centre left it are removed at a broad phase.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "dem/far_movers.hpp"
#include "dem/list_stamp.hpp"
#include "dem/pair_kernel.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"
#include "dem/tool_geometry.hpp"

namespace dem {

// Keeps the two largest of the squared displacements seen so far (first >= second), each of
// another particle: what the guard adds up.
inline void keep_two_largest(double& first, double& second, double d2) {
  if (d2 > second) {
    second = std::min(d2, first);
    first = std::max(d2, first);
  }
}

class Sleepers {
 public:
  // Sleepers are tracked per block of this many particles (by index): the box around a block's
  // sleepers spares the tool test of a whole block beyond every tool.
  static constexpr std::size_t kBlock = 64;

  Sleepers(const Scene& scene, int max_threads);

  // --- The region of interest and the arrays sleeping needs.
  // rest_steps is a sorted field: the broad phase permutes it, so it must have one entry per
  // particle before every build, with sleeping enabled or not (then it stays all zero).
  static void size_arrays(State& s);
  // Removes the particles outside the region (before a broad phase); removed_last() counts them.
  void remove_outside(State& s);
  void clear_removed() { removed_last_ = 0; }
  std::int64_t removed_last() const { return removed_last_; }

  // --- The pair loop.
  // The rules for this step's pair loop over s (n particles). With sleepers in the last step,
  // a sleeper's row is read only if it holds an awake partner (the counts are made when they do
  // not hold for s); without, or without `row_skip`, every row is read.
  detail::PairSleep pair_rules(State& s, bool row_skip);
  std::uint8_t* wake() { return wake_.data(); }
  std::vector<std::int32_t>& remote_wake(int t) { return remote_wake_[static_cast<std::size_t>(t)]; }
  void apply_remote_wakes(int T);  // after the loop, in thread order
  // The sleepers the pair loop woke, each once (its wake flag was clear), per thread (remote
  // wakes in thread 0's): the integration's wake test reads these instead of every flag.
  std::vector<std::int32_t>& woken(int t) { return woken_[static_cast<std::size_t>(t)]; }

  // --- The awake list: the particles awake at the start of this step, ascending. The pair
  // loop starts only their forces and the integration visits only them and the sleepers a wake
  // test needs (those the pair loop woke, those in a block within a tool's reach), so a sleeper
  // costs nothing in either. Made from rest_steps when it does not hold for s at this step (a
  // broad phase reordered the particles, a loaded checkpoint, another state), and kept up to
  // date from the step's wakes and sleeps after that (stepped()).
  const std::vector<std::int32_t>& awake(const State& s);
  // Held for s at its step (made by awake() this step or kept up to date): the engine uses it.
  bool awake_holds(const State& s) const { return awake_.holds(s, s.step); }

  // --- The integration.
  // Each tool's neighbourhood at s's tool poses (sphere or box, scene.sleep.neighbourhood).
  void make_neighbourhood(const State& s, const ToolGeometry& tools);
  // Is a particle at x with radius r within a tool's neighbourhood?
  bool near(const ToolGeometry& tools, Vec3 x, double r) const;
  // Are the sleepers of block b beyond every tool's neighbourhood (or is there none)?
  bool block_far(std::size_t b) const;

  // The sleepers' tally for the step of s about to be integrated, T threads: kept from the last
  // step, emptied after a broad phase, or to be noted again from every sleeper (returns true).
  bool begin_tally(const State& s, int T);
  // One thread's notes of the step: sleepers it adds to the tally, particles that woke or fell
  // asleep.
  struct ThreadNotes {
    double d1 = 0, d2 = 0;
    FarMoverGuard::Tally tally;
    std::vector<std::int32_t> far, woke, fell;
  };
  void begin_step() {
    awake_partners_.woke.clear();
    awake_partners_.fell.clear();
  }
  // Inside the threads' critical section: a thread's notes (`keep`: the tally is kept).
  void merge(const ThreadNotes& notes, bool keep);
  // After the threads: the tally into the step's totals (two largest displacements, far
  // movers' tally and list T of `guard`), the blocks' boxes grown; returns the far movers'
  // list count (T or T + 1).
  int end_tally(const State& s, int T, double& max_d2, double& second_d2,
                FarMoverGuard::Tally& tally, FarMoverGuard& guard);
  // After the step (s.step already the next): counters and awake partners brought up to date.
  void stepped(const State& s, std::int64_t sleeping);
  // Without sleeping: only the count.
  void set_sleeping(std::int64_t sleeping) { sleeping_ = sleeping; }

  std::int64_t sleeping() const { return sleeping_; }
  std::int64_t woke_total() const { return woke_total_; }
  std::int64_t fell_asleep_total() const { return fell_asleep_total_; }
  std::size_t bytes() const;

 private:
  const Scene& scene_;
  // wake_[i] set by the pair loop when a sleeper is to wake; wakes of particles in another
  // thread's range are queued per thread and applied after the loop.
  std::vector<std::uint8_t> wake_;
  std::vector<std::vector<std::int32_t>> remote_wake_;  // per thread
  std::vector<std::vector<std::int32_t>> woken_;        // per thread
  std::vector<std::uint8_t> remove_;                    // region of interest workspace
  std::int64_t removed_last_ = 0;

  // The awake partners of each row (State::pair_row), so that the pair loop reads a sleeper's
  // row only when it holds one. Counted once after a broad phase and kept up to date from the
  // particles that woke or fell asleep in each step (a few dozen per step in the paper's pile,
  // against 28,000 awake ones that would mark rows every step). Valid for the state, size,
  // lists and step stamped; counted again otherwise.
  struct AwakePartners {
    std::vector<std::int32_t> count;
    std::vector<std::int32_t> woke, fell;  // this step's transitions (the integration's)
    ListStamp stamp;
    bool holds(const State& s, std::int64_t at_step) const;  // kept for s at this step
    void add(const State& s, std::int32_t j, std::int32_t delta);
  };
  AwakePartners awake_partners_;
  struct AwakeList {
    std::vector<std::int32_t> list, next;  // next: workspace of the update
    ListStamp stamp;
    // (not ListStamp::built_at: stepped() runs before the step counts towards the broad phase)
    bool holds(const State& s, std::int64_t at_step) const {
      return stamp.matches(s, ListStamp::state | ListStamp::size | ListStamp::candidates |
                                  ListStamp::rebuilds | ListStamp::step,
                           at_step) &&
             static_cast<std::size_t>(s.size()) == s.rest_steps.size();
    }
  };
  AwakeList awake_;
  void update_awake_list(const State& s);
  void count_awake_partners(const State& s);
  void update_awake_partners(const State& s);

  // What the sleepers add to the guard's tallies (two largest displacements, the far movers'
  // tally and list). A sleeper's displacement since the broad phase is the one it fell asleep
  // with (0 for one asleep at the broad phase). Woken ones stay in it until the next broad
  // phase (an upper bound: the guard may rebuild earlier, never later). Valid for the state,
  // size, broad phase and step stamped; else every sleeper is noted again.
  struct Tally {
    double d1 = 0, d2 = 0;
    FarMoverGuard::Tally tally;
    std::vector<std::int32_t> far;
    // The box around the sleepers of each block, grown as particles fall asleep, made again
    // after each broad phase (it reorders them).
    std::vector<Vec3> box_lo, box_hi;
    std::vector<std::int32_t> fell_asleep;  // this step's, to grow the boxes after the loop
    ListStamp stamp;
    void clear() {
      d1 = d2 = 0;
      tally = FarMoverGuard::Tally{};
      far.clear();
    }
  };
  Tally tally_;
  void make_boxes(const State& s, int T);

  // This step's tool neighbourhoods: with neighbourhood: sphere, the sphere around each tool's
  // reference point with the mesh's bounding radius plus scene.sleep.tool_distance (plus the
  // particle radius); with box, the points within tool_distance (plus the particle radius) of
  // the mesh's box in the tool frame, and the world box around it (aabb) for a quick test.
  bool box_ = false;
  std::vector<Vec3> tool_centre_;
  std::vector<double> tool_reach_;
  std::vector<Vec3> aabb_lo_, aabb_hi_;
  double block_pad_ = 0;

  std::int64_t sleeping_ = 0;
  std::int64_t woke_total_ = 0, fell_asleep_total_ = 0;
};

// --- Inline: the integration calls these per particle.

inline bool Sleepers::near(const ToolGeometry& tools, Vec3 x, double r) const {
  for (std::size_t m = 0; m < tool_centre_.size(); ++m) {
    const double reach = tool_reach_[m] + r;
    const Vec3 d = x - tool_centre_[m];
    if (!box_) {
      if (norm2(d) < reach * reach) return true;
      continue;
    }
    // Outside the world box around the tool's box widened by the reach, or farther from the
    // reference point than the box's farthest corner plus the reach: not near the box (the
    // exact test below would say the same; margins of 1e-9 cover its rounding). Spares the
    // rotation for most of a large bed.
    const Vec3 a = aabb_lo_[m], z = aabb_hi_[m];
    const double rr = reach * (1 + 1e-9);
    if (x.x > z.x + rr || x.x < a.x - rr || x.y > z.y + rr || x.y < a.y - rr || x.z > z.z + rr ||
        x.z < a.z - rr)
      continue;
    const double bound = (tools.box_radius[m] + reach) * (1 + 1e-9);
    if (norm2(d) > bound * bound) continue;
    // d in the tool frame (R^T d), then its distance to the mesh's box
    const Vec3 q = to_frame(tools.rotation[m], d);
    const Vec3 lo = tools.box_min[m], hi = tools.box_max[m];
    const Vec3 out{std::max({lo.x - q.x, 0.0, q.x - hi.x}), std::max({lo.y - q.y, 0.0, q.y - hi.y}),
                   std::max({lo.z - q.z, 0.0, q.z - hi.z})};
    if (norm2(out) < reach * reach) return true;
  }
  return false;
}

inline bool Sleepers::block_far(std::size_t b) const {
  const Vec3 lo = tally_.box_lo[b], hi = tally_.box_hi[b];
  if (!(lo.x <= hi.x)) return true;  // no sleeper in it
  for (std::size_t m = 0; m < tool_centre_.size(); ++m) {
    const double reach = (tool_reach_[m] + block_pad_) * (1 + 1e-6);
    if (box_) {
      const Vec3 a = aabb_lo_[m], z = aabb_hi_[m];
      if (lo.x > z.x + reach || hi.x < a.x - reach || lo.y > z.y + reach || hi.y < a.y - reach ||
          lo.z > z.z + reach || hi.z < a.z - reach)
        continue;
      return false;
    }
    const Vec3 c = tool_centre_[m];
    const Vec3 out{std::max({lo.x - c.x, 0.0, c.x - hi.x}), std::max({lo.y - c.y, 0.0, c.y - hi.y}),
                   std::max({lo.z - c.z, 0.0, c.z - hi.z})};
    if (!(norm2(out) > reach * reach)) return false;
  }
  return true;
}

}  // namespace dem
