// Broad phase on a uniform cell grid: sorts particles by cell (cache locality), lists
// particle pairs and particle-triangle pairs within the skin, and carries the tangential
// history of pairs that persist from the previous list to the new one.
#pragma once

#include <cstdint>
#include <vector>

#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem {

class BroadPhase {
 public:
  // tool_vertices[m]: world positions of tool m's mesh vertices at the current pose.
  void build(const Scene& scene, State& s, const std::vector<std::vector<Vec3>>& tool_vertices,
             int threads);

 private:
  // Workspace kept between builds so the steady state allocates nothing new.
  std::vector<std::int32_t> cell_of_, cell_start_, order_, new_index_;
  std::vector<Vec3> scratch_vec_;
  std::vector<double> scratch_d_;
  std::vector<std::int32_t> scratch_i32_;
  std::vector<std::int64_t> scratch_i64_;
  std::vector<std::uint64_t> scratch_key_;
  std::vector<std::uint8_t> scratch_u8_;
  std::vector<std::vector<std::int32_t>> thread_j_;
  std::vector<std::size_t> thread_used_;
  std::vector<std::int32_t> old_offset_, old_j_;
  std::vector<Vec3> old_spring_;
  struct TriCandidate {
    std::int32_t particle, tool, tri;
  };
  std::vector<TriCandidate> tri_candidates_;
  std::vector<std::vector<TriCandidate>> thread_tri_;  // per thread, joined in thread order
  std::vector<std::int32_t> tri_count_;
  int threads_ = 1;

  template <class T>
  void permute(std::vector<T>& a, std::vector<T>& scratch, std::size_t width);
};

}  // namespace dem
