// Broad phase on a uniform cell grid: sorts particles by cell (cache locality), lists
// particle pairs and particle-triangle pairs within the skin, and carries the tangential
// history of pairs that persist from the previous list to the new one. Its named stages are
// timed (stages()); docs/performance.md says what each costs.
#pragma once

#include <cstdint>
#include <vector>

#include "cosim/timer.hpp"
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
// The distance test of the pair list for particle a over its stencil rows: the candidates b in
// [max(row_begin[q], a + 1), row_end[q]) for q < rows whose centre distance is below
// r_a + r_b + skin, written to `out` in order; their number is returned, and those already
// touching (distance below r_a + r_b) are added to `touching`. Positions and radii come as
// separate arrays in cell order. row_hits_vector does it 8 candidates at a time with AVX-512
// where the processor has it (row_hits_vector_available) and makes exactly the decisions of
// row_hits_scalar (same operations in the same order, no contraction), so the list does not
// depend on the processor; without AVX-512 it is row_hits_scalar.
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
// Which test the broad phase uses from now on: the vector one where available (the default) or
// the scalar one everywhere (tests compare whole runs with both).
void use_vector_row_test(bool vector);
}  // namespace detail

class BroadPhase {
 public:
  // tool_vertices[m]: world positions of tool m's mesh vertices at the current pose.
  void build(const Scene& scene, State& s, const std::vector<std::vector<Vec3>>& tool_vertices,
             int threads);

  // Wall-clock seconds per stage of build(), summed over all builds.
  const cosim::Timer& stages() const { return stages_; }
  cosim::Timer& stages() { return stages_; }

  // Bytes of workspace kept between builds (old list, scratch, cell grid).
  std::size_t workspace_bytes() const;

  // Particles moved by the last build's permutation (0 when the cell order had not changed).
  std::size_t last_permuted() const { return last_permuted_; }

 private:
  cosim::Timer stages_{{"grid", "sort", "permute", "pair_list", "history", "mesh_candidates",
                        "wall_masks"}};
  std::size_t last_permuted_ = 0;

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
  struct TriCandidate {
    std::int32_t particle, tool, tri;
  };
  std::vector<TriCandidate> tri_candidates_;
  std::vector<std::vector<TriCandidate>> thread_tri_;  // per thread, joined in thread order
  std::vector<std::int32_t> tri_count_;
  int threads_ = 1;

  // a[p0..p1) = a[order_[p]] for p in [p0, p1): the window of the order that changed.
  template <class T>
  void permute(std::vector<T>& a, std::size_t p0, std::size_t p1);
  void boundary_slots(const Scene& scene, State& s, double skin);
};

}  // namespace dem
