// Broad phase on a uniform cell grid: sorts particles by cell (cache locality), lists
// particle pairs and particle-triangle pairs within the skin, and carries the tangential
// history of pairs that persist from the previous list to the new one. Its named stages are
// timed (stages()); docs/performance.md says what each costs.
#pragma once

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

#include "cosim/timer.hpp"
#include "dem/list_stamp.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem {

// The stages of BroadPhase::build, in order: the rows of stages().
namespace stage {
enum : std::size_t {
  grid,             // bounding box and cell size
  sort,             // cell of every particle, stable counting sort
  permute,          // particle arrays into cell order (only the part whose order changed)
  pair_list,        // half list of particle pairs within the skin
  history,          // tangential springs of persisting pairs carried to the new list
  mesh_candidates,  // particle-triangle pairs, per triangle over the cells its box covers
  wall_masks,       // walls near each particle, reference positions, boundary history slots
};
}  // namespace stage

namespace detail {
// Cells at least h wide over the box [lo, hi] (h is grown by 1.25 until there are at most
// max_cells: a body far from the rest would blow the count up).
inline void grid_cells(Vec3 lo, Vec3 hi, double max_cells, double& h, long& nx, long& ny,
                       long& nz) {
  while (true) {
    nx = static_cast<long>((hi.x - lo.x) / h) + 1;
    ny = static_cast<long>((hi.y - lo.y) / h) + 1;
    nz = static_cast<long>((hi.z - lo.z) / h) + 1;
    if (static_cast<double>(nx) * ny * nz <= max_cells) return;
    h *= 1.25;
  }
}

// The distance test of the pair list for particle a over its stencil rows: the candidates b in
// [max(row_begin[q], a + 1), row_end[q]) for q < rows whose centre distance is below
// r_a + r_b + skin, written to `out` in order; their number is returned, and those already
// touching (distance below r_a + r_b) are added to `touching`. Positions and radii come as
// separate arrays in cell order. row_hits_vector does it 8 candidates at a time with AVX-512
// where the processor has it, else 4 at a time with AVX2 (row_hits_vector_available: either),
// and makes exactly the decisions of row_hits_scalar (same operations in the same order, no
// contraction), so the list does not depend on the processor; with neither it is
// row_hits_scalar. row_hits_avx2 is the AVX2 test whatever else the processor has (the scalar
// one without AVX2), for the tests. `out` must have room for kRowHitsSlack entries past the
// candidates: the vector tests store 8 or 4 lanes at a time.
constexpr std::size_t kRowHitsSlack = 8;
struct RowData {
  const double* x;
  const double* y;
  const double* z;
  const double* r;
};
std::int32_t row_hits_scalar(const RowData& d, Vec3 xa, double ra, double skin, std::int32_t a,
                             const std::int32_t* row_begin, const std::int32_t* row_end,
                             int rows, std::int32_t* out, std::int32_t& touching);
std::int32_t row_hits_vector(const RowData& d, Vec3 xa, double ra, double skin, std::int32_t a,
                             const std::int32_t* row_begin, const std::int32_t* row_end,
                             int rows, std::int32_t* out, std::int32_t& touching);
bool row_hits_vector_available();
std::int32_t row_hits_avx2(const RowData& d, Vec3 xa, double ra, double skin, std::int32_t a,
                           const std::int32_t* row_begin, const std::int32_t* row_end, int rows,
                           std::int32_t* out, std::int32_t& touching);
bool row_hits_avx2_available();
}  // namespace detail

class BroadPhase {
 public:
  // tool_vertices[m]: world positions of tool m's mesh vertices at the current pose.
  void build(const Scene& scene, State& s, const std::vector<std::vector<Vec3>>& tool_vertices,
             int threads);

  // Which distance test the pair list uses: the vector one where available (the default) or the
  // scalar one everywhere (EngineOptions::vector_row_test; the same lists).
  void use_vector_row_test(bool vector);
  // How the history is carried over: rows whose new row lists the same partners (renumbered or
  // not) copy their springs in place (the default), or every held spring is looked up in its
  // new row (EngineOptions::history_same_rows; the same springs).
  void use_history_same_rows(bool same_rows);
  // Rows of the old lists whose history was copied in place / looked up, over all builds.
  std::int64_t history_rows_copied() const { return rows_copied_; }
  std::int64_t history_rows_looked_up() const { return rows_looked_up_; }

  // Wall-clock seconds per stage of build(), summed over all builds.
  const cosim::Timer& stages() const { return stages_; }
  cosim::Timer& stages() { return stages_; }

  // Bytes of workspace kept between builds (old list, scratch, cell grid).
  std::size_t workspace_bytes() const;

  // Particles moved by the last build's permutation (0 when the cell order had not changed).
  std::size_t last_permuted() const { return last_permuted_; }

  // Whether the grid below is the one of s's last broad phase (built by this object), and, if
  // not, rebuilding it from s (false when s's lists are not in cell order, e.g. not valid).
  bool grid_matches(const State& s) const;
  bool restore_grid(const Scene& scene, const State& s);

  // After build() and until the next one (the particles keep their order in between): calls
  // f(b) for every particle b whose cell at that build overlaps the box p +- reach, a superset
  // of the particles whose position at the build (State::x_at_rebuild) was within reach of p.
  // The guard's far-mover check (Engine) looks for new neighbours this way.
  // Check grid_matches(s) (or restore_grid) first.
  template <class F>
  void for_each_near(Vec3 p, double reach, F&& f) const {
    const long x0 = cell_coord(p.x - reach, lo_.x, nx_), x1 = cell_coord(p.x + reach, lo_.x, nx_);
    const long y0 = cell_coord(p.y - reach, lo_.y, ny_), y1 = cell_coord(p.y + reach, lo_.y, ny_);
    const long z0 = cell_coord(p.z - reach, lo_.z, nz_), z1 = cell_coord(p.z + reach, lo_.z, nz_);
    for (long z = z0; z <= z1; ++z)
      for (long y = y0; y <= y1; ++y) {
        const long row = (z * ny_ + y) * nx_;
        for (std::int32_t b = cell_start_[row + x0]; b < cell_start_[row + x1 + 1]; ++b) f(b);
      }
  }

 private:
  cosim::Timer stages_{{"grid", "sort", "permute", "pair_list", "history", "mesh_candidates",
                        "wall_masks"}};
  std::size_t last_permuted_ = 0;
  // The last build's grid: lower corner, 1 / cell size, cells per axis.
  Vec3 lo_{};
  double inv_h_ = 1;
  long nx_ = 0, ny_ = 0, nz_ = 0;
  // Which broad phase the grid is of: the state, its size, s.rebuilds and the step it ran at.
  ListStamp grid_stamp_;
  static constexpr unsigned kGridFields =
      ListStamp::state | ListStamp::size | ListStamp::rebuilds | ListStamp::built_at;
  void set_grid(Vec3 lo, Vec3 hi, std::size_t n, double h);
  // The grid's cell along one axis of coordinate v, clamped to [0, nmax) (NaN: 0).
  long cell_coord(double v, double l, long nmax) const {
    const double a = (v - l) * inv_h_;
    return a > 0 ? (a < static_cast<double>(nmax) ? static_cast<long>(a) : nmax - 1) : 0;
  }
  long cell_index(Vec3 p) const {
    return (cell_coord(p.z, lo_.z, nz_) * ny_ + cell_coord(p.y, lo_.y, ny_)) * nx_ +
           cell_coord(p.x, lo_.x, nx_);
  }

  // Workspace kept between builds so the steady state allocates nothing new.
  std::vector<std::int32_t> cell_of_, cell_start_, fill_, order_, new_index_;
  std::vector<unsigned char> scratch_;  // permutation buffer, for arrays of any type
  std::vector<std::vector<std::int32_t>> thread_j_;
  std::vector<std::size_t> thread_used_, thread_base_;
  std::vector<std::int64_t> work_base_;
  std::vector<std::int32_t> old_offset_, old_j_;
  std::vector<Vec3> old_spring_;
  std::vector<double> px_, py_, pz_, pr_;  // positions and radii in cell order, for the pair list
  std::vector<std::uint64_t> pool_key_;  // the next boundary slot pool, swapped in
  std::vector<Vec3> pool_spring_;
  std::vector<Vec3> old_roll_, pool_roll_;  // the rotating model's rolling springs (dem/rotation.hpp)
  struct TriCandidate {
    std::int32_t particle, tool, tri;
  };
  std::vector<TriCandidate> tri_candidates_;
  std::vector<std::vector<TriCandidate>> thread_tri_;  // per thread, joined in thread order
  std::vector<std::int32_t> tri_count_;
  int threads_ = 1;
  bool vector_row_test_ = true;
  bool history_same_rows_ = true;
  std::int64_t rows_copied_ = 0, rows_looked_up_ = 0;

  // a[p0..p1) = a[order_[p]] for p in [p0, p1): the window of the order that changed.
  template <class T>
  void permute(std::vector<T>& a, std::size_t p0, std::size_t p1);
  // The stages of build(), in order (their rows in stages()).
  void make_grid(const State& s, int T, double rmax, double skin);  // grid, particles' box
  std::pair<std::size_t, std::size_t> sort_by_cell(const State& s, int T);  // changed window
  bool permute_state(State& s, std::size_t p0, std::size_t p1);  // true: an old list to carry
  void list_pairs(State& s, int T, double skin);
  void carry_history(State& s, int T);
  void list_mesh_candidates(const Scene& scene, State& s,
                            const std::vector<std::vector<Vec3>>& tool_vertices, int T,
                            double skin);
  void boundary_slots(const Scene& scene, State& s, double skin);
  Vec3 box_lo_{}, box_hi_{};  // the particles' box at the last build (make_grid)
};

}  // namespace dem
