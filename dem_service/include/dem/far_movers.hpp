// The broad phase's guard (docs/dem.md "The guard"): the lists hold every contact until the
// bodies together moved more than the skin since the last broad phase. Its bound adds up the
// two largest displacements, the step's contact window and each tool's move; when the bound
// fires, the far-mover check (scene.guard: rebuild) looks at the few particles that moved more
// than half the skin (the far movers) where they are now, and spares the broad phase when none
// of them has come near a particle, wall or tool it is not listed with.
//
// The far movers of the state after a step are collected by the integration, per thread
// (note(), thread_list()), and finished here; find() collects them for any other state.
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "dem/broad_phase.hpp"
#include "dem/list_stamp.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"
#include "dem/tool_geometry.hpp"

namespace dem {

class FarMoverGuard {
 public:
  // At most this many far movers are listed (else the check gives up: a broad phase runs).
  static constexpr std::size_t kMaxFarMovers = 1024;

  // The largest squared displacement and speed of the particles that moved at most half the
  // skin (the others), and the largest squared speed of all.
  struct Tally {
    double near2 = 0, near_u2 = 0, u2 = 0;
    void merge(const Tally& o) {
      near2 = std::max(near2, o.near2);
      near_u2 = std::max(near_u2, o.near_u2);
      u2 = std::max(u2, o.u2);
    }
  };
  struct Limits {
    double d2, u2;  // far beyond either (squared displacement, squared speed)
  };
  // Far if it moved more than 0.9 of half the skin or its half step dt/2 |u| (its part of the
  // contact window) exceeds 0.1 of it (NaN counts as far); so every other particle has
  // d + dt/2 |u| <= skin / 2, and no pair of two of them is inside its window yet.
  static Limits limits(const Scene& scene);
  // One particle's share (d2 its squared displacement since the broad phase, ui2 its squared
  // speed). Listed up to one past the cap so that finish() sees an overflow.
  static void note(std::vector<std::int32_t>& far, Tally& tally, std::size_t i, double d2,
                   double ui2, const Limits& limits) {
    tally.u2 = std::max(tally.u2, ui2);
    if (!(d2 <= limits.d2 && ui2 <= limits.u2)) {
      if (far.size() <= kMaxFarMovers) far.push_back(static_cast<std::int32_t>(i));
    } else {
      tally.near2 = std::max(tally.near2, d2);
      tally.near_u2 = std::max(tally.near_u2, ui2);
    }
  }

  // The integration's per-thread lists (ascending ranges): `lists` of them.
  void size_lists(std::size_t lists) { thread_far_.resize(lists); }
  std::vector<std::int32_t>& thread_list(std::size_t t) { return thread_far_[t]; }
  // The far movers of state s from the first `lists` per-thread lists and the merged tally;
  // with `merge_sorted`, lists that may overlap (a woken sleeper in two) are made ascending and
  // each once.
  void finish(const State& s, int lists, const Tally& tally, bool merge_sorted = false);

  // The bound: true when it exceeds the skin (*moved: the bound, m).
  bool fires(const Scene& scene, const State& s, double* moved);
  // The bound itself from s's two largest displacements and the largest speed |u| of any
  // particle (fires() with its own tally; the MPI driver, dem/mpi/, with the ranks' reduced one).
  static double bound(const Scene& scene, const State& s, double u_max);
  // The far-mover check: true when the lists still hold every contact.
  bool clear(const Scene& scene, const State& s, BroadPhase& broad, const ToolGeometry& tools);
  // The strict guard's error for a bound `moved` that fired.
  static std::string strict_message(const Scene& scene, const State& s, double moved);
  // Counts a step whose broad phase the check spared (once per step: prepare() may run twice).
  void count_cleared(const State& s) {
    if (cleared_at_ != s.step) ++cleared_;
    cleared_at_ = s.step;
  }
  std::int64_t cleared() const { return cleared_; }

  // How far any point of tool m moved since the last broad phase (at most), and half a step of
  // its fastest point (its part of the contact window).
  static double tool_move(const Scene& scene, const State& s, std::size_t m);
  static double tool_window(const Scene& scene, const State& s, std::size_t m);

 private:
  void find(const Scene& scene, const State& s);
  // Each tool's triangles binned on a grid in the mesh frame (built when the check first needs
  // it; meshes are rigid): the triangles near a point without a pass over all.
  struct MeshGrid {
    Vec3 lo{};
    double inv_h = 1;
    long nx = 0, ny = 0, nz = 0;
    std::vector<std::int32_t> start, tri;
  };
  void build_mesh_grids(const Scene& scene);
  // Is a triangle of tool m within `reach` of particle e that is not among e's candidates?
  bool unlisted_triangle_near(const Scene& scene, const State& s, const ToolGeometry& tools,
                              std::size_t e, std::size_t m, double reach) const;

  // Far movers: particles that moved more than half the skin since the last broad phase, in
  // ascending order (at most kMaxFarMovers, else overflow_), with the largest displacement of
  // all the others and the largest speed |u| of any particle; valid for the state and step
  // stamped (the state object, its size and its step).
  std::vector<std::int32_t> far_;
  std::vector<std::uint8_t> far_flag_;  // clear(): 1 for the far movers, else 0
  std::vector<std::vector<std::int32_t>> thread_far_;  // per thread
  bool overflow_ = false;
  double near_max_ = 0, near_u_max_ = 0, u_max_ = 0;
  ListStamp stamp_;
  static constexpr unsigned kStampFields = ListStamp::state | ListStamp::size | ListStamp::step;
  std::int64_t cleared_ = 0, cleared_at_ = -1;
  std::vector<double> tool_moves_;  // each tool's move since the broad phase, with its window
  std::vector<MeshGrid> mesh_grid_;
};

}  // namespace dem
