#include "dem/sleepers.hpp"

#include <omp.h>

#include <algorithm>
#include <cstring>
#include <limits>

namespace dem {

Sleepers::Sleepers(const Scene& scene, int max_threads) : scene_(scene) {
  remote_wake_.resize(static_cast<std::size_t>(max_threads));
  woken_.resize(static_cast<std::size_t>(max_threads));
}

void Sleepers::size_arrays(State& s) {
  if (s.rest_steps.size() != s.size()) s.rest_steps.resize(s.size(), 0);
}

void Sleepers::remove_outside(State& s) {
  removed_last_ = 0;
  if (!scene_.region.enabled) return;
  const std::size_t n = s.size();
  const Vec3 lo = scene_.region.min, hi = scene_.region.max;
  remove_.assign(n, 0);
  bool any = false;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 p = s.x[i];
    // NaN compares false: a NaN particle is left for the blow-up check to name.
    const bool out = p.x < lo.x || p.y < lo.y || p.z < lo.z || p.x > hi.x || p.y > hi.y ||
                     p.z > hi.z;
    remove_[i] = out;
    any = any || out;
  }
  if (any) removed_last_ = static_cast<std::int64_t>(remove_particles(s, remove_));
}

// --- The pair loop.

bool Sleepers::AwakePartners::holds(const State& s, std::int64_t at_step) const {
  return stamp.matches(s, ListStamp::state | ListStamp::size | ListStamp::candidates |
                              ListStamp::rebuilds | ListStamp::step,
                       at_step) &&
         count.size() == s.size() && s.pair_row_offset.size() == s.size() + 1;
}

// The rows that hold particle j (State::pair_row) gain `delta` awake partners.
void Sleepers::AwakePartners::add(const State& s, std::int32_t j, std::int32_t delta) {
  const std::int32_t* const ro = s.pair_row_offset.data();
  const std::int32_t* const rr = s.pair_row.data();
  for (std::int32_t q = ro[j]; q < ro[j + 1]; ++q) count[static_cast<std::size_t>(rr[q])] += delta;
}

// For each row of the half list, the number of its partners that are awake (State::pair_row
// lists the rows that hold each particle).
void Sleepers::count_awake_partners(const State& s) {
  AwakePartners& a = awake_partners_;
  const std::size_t n = s.size();
  const std::int32_t S = scene_.sleep.steps;
  a.count.assign(n, 0);
  for (std::size_t j = 0; j < n; ++j)
    if (s.rest_steps[j] < S) a.add(s, static_cast<std::int32_t>(j), 1);
  a.stamp.take(s);
}

// After the integration of a step (s.step already the next one): the rows that hold a particle
// that woke gain an awake partner, those that hold one that fell asleep lose one. Only if the
// counts were those of the step just made; else they are counted again when next needed.
void Sleepers::update_awake_partners(const State& s) {
  AwakePartners& a = awake_partners_;
  if (!a.holds(s, s.step - 1)) {
    a.stamp.clear();
    return;
  }
  for (const std::int32_t j : a.woke) a.add(s, j, 1);
  for (const std::int32_t j : a.fell) a.add(s, j, -1);
  a.stamp.set_step(s.step);
}

detail::PairSleep Sleepers::pair_rules(State& s, bool row_skip) {
  const std::size_t n = s.size();
  wake_.resize(n);
  // A sleeper's row is scanned only if an awake particle is among its partners (the rows of
  // two sleepers compute nothing). Without sleepers in the last step every row is read and
  // nothing is counted or built; the pairs computed are the same either way.
  const bool skip_rows = sleeping_ > 0 && row_skip;
  if (skip_rows) {
    // Built by the first step with sleeping after a broad phase (and again if a loaded
    // checkpoint's copy does not fit the lists).
    if (s.pair_row_offset.size() != n + 1 || s.pair_row.size() != s.pair_j.size() ||
        static_cast<std::size_t>(s.pair_row_offset[n]) != s.pair_row.size()) {
      build_pair_rows(s);
      awake_partners_.stamp.clear();
    }
    if (!awake_partners_.holds(s, s.step)) count_awake_partners(s);
  }
  for (std::vector<std::int32_t>& w : woken_) w.clear();
  awake(s);  // this step's, for start_forces and the integration
  detail::PairSleep rules;
  rules.rest = s.rest_steps.data();
  rules.steps = scene_.sleep.steps;
  rules.wake_speed2 = scene_.sleep.wake() * scene_.sleep.wake();
  rules.awake_partners = skip_rows ? awake_partners_.count.data() : nullptr;
  rules.wake = wake_.data();
  return rules;
}

void Sleepers::apply_remote_wakes(int T) {
  for (int t = 0; t < T; ++t)
    for (const std::int32_t p : remote_wake_[static_cast<std::size_t>(t)])
      if (!wake_[p]) {
        wake_[p] = 1;
        woken_[0].push_back(p);
      }
}

// --- The awake list.

const std::vector<std::int32_t>& Sleepers::awake(const State& s) {
  AwakeList& a = awake_;
  if (a.holds(s, s.step)) return a.list;
  const std::size_t n = s.size();
  const std::int32_t S = scene_.sleep.steps;
  const std::int32_t* const REST = s.rest_steps.data();
  a.list.clear();
  for (std::size_t i = 0; i < n; ++i)
    if (REST[i] < S) a.list.push_back(static_cast<std::int32_t>(i));
  a.stamp.take(s);
  return a.list;
}

// After the integration of a step (s.step already the next one): those that fell asleep leave
// the list, those that woke join it, in order. Only if the list was this step's; else it is made
// again when next needed.
void Sleepers::update_awake_list(const State& s) {
  AwakeList& a = awake_;
  if (!a.holds(s, s.step - 1)) {
    a.stamp.clear();
    return;
  }
  std::vector<std::int32_t>& woke = awake_partners_.woke;
  std::vector<std::int32_t>& fell = awake_partners_.fell;
  if (!woke.empty() || !fell.empty()) {
    // The threads' notes arrive in any order: the list is kept ascending.
    std::sort(woke.begin(), woke.end());
    std::sort(fell.begin(), fell.end());
    a.next.clear();
    a.next.reserve(a.list.size() + woke.size());
    std::size_t w = 0, f = 0;
    for (const std::int32_t i : a.list) {
      while (w < woke.size() && woke[w] < i) a.next.push_back(woke[w++]);
      if (f < fell.size() && fell[f] == i) {
        ++f;
        continue;
      }
      a.next.push_back(i);
    }
    while (w < woke.size()) a.next.push_back(woke[w++]);
    a.list.swap(a.next);
  }
  a.stamp.set_step(s.step);
}

// --- The integration.

void Sleepers::make_neighbourhood(const State& s, const ToolGeometry& tools) {
  const std::size_t ntools = scene_.tools.size();
  box_ = scene_.sleep.neighbourhood == SleepNeighbourhood::box;
  tool_centre_.resize(ntools);
  tool_reach_.resize(ntools);
  for (std::size_t m = 0; m < ntools; ++m) {
    tool_centre_[m] = s.tool_pose[m].position;
    tool_reach_[m] = (box_ ? 0.0 : scene_.tools[m].mesh.bounding_radius) + scene_.sleep.tool_distance;
  }
  // With neighbourhood: box, the world frame's box around each tool's box (its frame's box
  // turned into the world), widened by the reach and a margin for rounding: a point outside
  // it is not within the reach of the tool's box, so near() skips the rotation for it.
  aabb_lo_.resize(box_ ? ntools : 0);
  aabb_hi_.resize(aabb_lo_.size());
  for (std::size_t m = 0; m < aabb_lo_.size(); ++m) {
    const Mat3& R = tools.rotation[m];
    const Vec3 c = 0.5 * (tools.box_min[m] + tools.box_max[m]), h = 0.5 * (tools.box_max[m] - tools.box_min[m]);
    const Vec3 cw = tool_centre_[m] + Vec3{R.m[0][0] * c.x + R.m[0][1] * c.y + R.m[0][2] * c.z,
                                           R.m[1][0] * c.x + R.m[1][1] * c.y + R.m[1][2] * c.z,
                                           R.m[2][0] * c.x + R.m[2][1] * c.y + R.m[2][2] * c.z};
    const Vec3 hw{std::abs(R.m[0][0]) * h.x + std::abs(R.m[0][1]) * h.y + std::abs(R.m[0][2]) * h.z,
                  std::abs(R.m[1][0]) * h.x + std::abs(R.m[1][1]) * h.y + std::abs(R.m[1][2]) * h.z,
                  std::abs(R.m[2][0]) * h.x + std::abs(R.m[2][1]) * h.y + std::abs(R.m[2][2]) * h.z};
    const double margin = 1e-9 * (norm(cw) + norm(hw) + tool_reach_[m] + 1.0);
    const Vec3 w = hw + Vec3{margin, margin, margin};
    aabb_lo_[m] = cw - w;
    aabb_hi_[m] = cw + w;
  }
  // Whole blocks of sleepers (any radius up to r_max) against each tool's neighbourhood.
  block_pad_ = scene_.r_max() * (1 + 1e-6);
}

// Right after a broad phase every sleeper's displacement is 0, so the tally starts empty; in
// any other step it does not belong to, every sleeper is noted again.
bool Sleepers::begin_tally(const State& s, int T) {
  Tally& k = tally_;
  const bool same = k.stamp.matches(s, ListStamp::state | ListStamp::size | ListStamp::step);
  bool renote = false, rebox = true;
  if (same && k.stamp.rebuilds_seen() + 1 == s.rebuilds && s.steps_since_rebuild == 0) {
    k.clear();
  } else if (!(same && k.stamp.matches(s, ListStamp::rebuilds))) {
    k.clear();
    renote = true;
  } else {
    rebox = false;
  }
  if (rebox) make_boxes(s, T);
  k.fell_asleep.clear();
  return renote;
}

// The sleepers' boxes per block, from every sleeper.
void Sleepers::make_boxes(const State& s, int T) {
  Tally& k = tally_;
  const std::size_t n = s.size();
  const std::int32_t S = scene_.sleep.steps;
  const std::size_t nb = (n + kBlock - 1) / kBlock;
  k.box_lo.resize(nb);
  k.box_hi.resize(nb);
  const std::int32_t* const REST = s.rest_steps.data();
  const Vec3* const X = s.x.data();
  constexpr double inf = std::numeric_limits<double>::infinity();
#pragma omp parallel for num_threads(T) schedule(static)
  for (std::size_t b = 0; b < nb; ++b) {
    Vec3 lo{inf, inf, inf}, hi{-inf, -inf, -inf};
    const std::size_t i1 = std::min(n, (b + 1) * kBlock);
    for (std::size_t i = b * kBlock; i < i1; ++i)
      if (REST[i] >= S) {
        lo = {std::min(lo.x, X[i].x), std::min(lo.y, X[i].y), std::min(lo.z, X[i].z)};
        hi = {std::max(hi.x, X[i].x), std::max(hi.y, X[i].y), std::max(hi.z, X[i].z)};
      }
    k.box_lo[b] = lo;
    k.box_hi[b] = hi;
  }
}

void Sleepers::merge(const ThreadNotes& notes, bool keep) {
  AwakePartners& a = awake_partners_;
  a.woke.insert(a.woke.end(), notes.woke.begin(), notes.woke.end());
  a.fell.insert(a.fell.end(), notes.fell.begin(), notes.fell.end());
  if (!keep) return;
  Tally& k = tally_;
  keep_two_largest(k.d1, k.d2, notes.d1);
  keep_two_largest(k.d1, k.d2, notes.d2);
  k.tally.merge(notes.tally);
  k.far.insert(k.far.end(), notes.far.begin(), notes.far.end());
  k.fell_asleep.insert(k.fell_asleep.end(), notes.fell.begin(), notes.fell.end());
}

int Sleepers::end_tally(const State& s, int T, double& max_d2, double& second_d2,
                        FarMoverGuard::Tally& tally, FarMoverGuard& guard) {
  Tally& k = tally_;
  int lists = T;
  keep_two_largest(max_d2, second_d2, k.d1);
  keep_two_largest(max_d2, second_d2, k.d2);
  tally.merge(k.tally);
  constexpr std::size_t cap = FarMoverGuard::kMaxFarMovers + 1;
  if (k.far.size() > cap) k.far.resize(cap);  // overflows anyway
  if (!k.far.empty()) {
    guard.size_lists(static_cast<std::size_t>(T) + 1);
    guard.thread_list(static_cast<std::size_t>(T)) = k.far;
    lists = T + 1;
  }
  for (const std::int32_t i : k.fell_asleep) {  // their blocks' boxes grow
    const std::size_t b = static_cast<std::size_t>(i) / kBlock;
    const Vec3 x = s.x[static_cast<std::size_t>(i)];
    Vec3& lo = k.box_lo[b];
    Vec3& hi = k.box_hi[b];
    lo = {std::min(lo.x, x.x), std::min(lo.y, x.y), std::min(lo.z, x.z)};
    hi = {std::max(hi.x, x.x), std::max(hi.y, x.y), std::max(hi.z, x.z)};
  }
  k.stamp.take(s, s.step + 1);  // the step this integration ends in
  return lists;
}

void Sleepers::stepped(const State& s, std::int64_t sleeping) {
  sleeping_ = sleeping;
  woke_total_ += static_cast<std::int64_t>(awake_partners_.woke.size());
  fell_asleep_total_ += static_cast<std::int64_t>(awake_partners_.fell.size());
  update_awake_partners(s);
  update_awake_list(s);
}

std::size_t Sleepers::bytes() const {
  std::size_t b = awake_partners_.count.capacity() + awake_partners_.woke.capacity() +
                  awake_partners_.fell.capacity() + awake_.list.capacity() + awake_.next.capacity();
  for (const auto& w : woken_) b += w.capacity();
  return b * sizeof(std::int32_t);
}

}  // namespace dem
