// Wall and mesh (tool) contacts: each particle with a boundary slot block (the broad phase
// handed them out) gathers its walls and the mesh features of its triangle candidates, keeps
// or hands on the tangential springs of its slot block, and sums the forces on itself, on each
// wall and on each tool. The particles are cut into chunks, a number that depends on the
// blocks alone; each chunk sums its tools' and walls' forces on its own, is run by the thread
// that claims it first, and the chunks' sums are added in chunk order: the same bits on any
// thread count.
#pragma once

#include <cstdint>
#include <vector>

#include "dem/engine_types.hpp"
#include "dem/mesh_contact.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"
#include "dem/tool_geometry.hpp"

namespace dem {

class BoundaryContacts {
 public:
  explicit BoundaryContacts(const Scene& scene, int max_threads);

  // Adds the wall and mesh forces of this step to force[i] (sleepers have none) on T threads;
  // busy[t] gains thread t's working seconds. Throws SimulationError naming the particle that
  // touches more than kBoundarySlots features. torque: the rotating model's torques
  // (dem/rotation.hpp), which the contacts add to and whose contacts see the spins; nullptr:
  // the translating model.
  // ghost: nullptr, or per particle 1 for another rank's copy (dem/mpi/), which is skipped:
  // no force, no wrench, no wall force, no stat.
  void forces(State& s, const ToolGeometry& tools, Vec3* force, int T, double* busy,
              Vec3* torque = nullptr, const std::uint8_t* ghost = nullptr);
  // forces() in three parts, for a caller that runs the threads' part inside a parallel region
  // of its own (Engine's one region per step): begin() (one thread, before; false: no wall and
  // no tool, nothing to do), run() (every thread t of the T in the region, each once; a thread
  // may start while another is still in run()), end() (one thread, after every run(): throws
  // the SimulationError of a particle with too many contacts, sums the chunks' forces on the
  // walls and tools). overflowed(): a run() found such a particle (read after every run()).
  // wait (optional): before a chunk, run() calls wait->fn(wait->ctx, lo, hi) with the lowest and
  // highest particle of the chunk, which returns once force[lo..hi] is complete (the seconds
  // waited, left out of busy): a caller whose other threads may still be adding to force.
  struct ChunkWait {
    double (*fn)(const void* ctx, std::size_t lo, std::size_t hi) = nullptr;
    const void* ctx = nullptr;
  };
  bool begin(State& s, const Vec3* torque = nullptr);
  void run(State& s, const ToolGeometry& tools, Vec3* force, int t, int T, double* busy,
           Vec3* torque = nullptr, const std::uint8_t* ghost = nullptr,
           const ChunkWait* wait = nullptr);
  void end(State& s);
  bool overflowed() const { return overflow_ >= 0; }

  // false runs the boundary contacts as before the fast path (no fetching ahead, a resting
  // contact's spring matched by the search, the springs zeroed for every particle): the same
  // bits, slower (EngineOptions::boundary_fast; docs/performance.md "The boundary contacts").
  void use_fast_path(bool fast) { fast_ = fast; }
  // true (the default) lets the fast path test a sphere's candidate triangles 4 at a time where
  // the processor can (triangles_within; the same decisions), false one at a time
  // (EngineOptions::vector_triangle_test).
  void use_triangle_lanes(bool lanes) {
    triangle_lanes_ = lanes && triangles_within_lanes_available();
  }

  const std::vector<Wrench>& tool_wrenches() const { return tool_wrench_; }
  const std::vector<Vec3>& wall_forces() const { return wall_force_; }
  const ContactStats& thread_stats(int t) const { return thread_stats_[t]; }

  // Mesh contacts after feature selection at the current positions (for tests).
  struct MeshContact {
    std::int64_t particle;
    int tool;
    std::uint64_t key;
    Vec3 point;
  };
  std::vector<MeshContact> mesh_contacts(const State& s, const ToolGeometry& tools) const;
  std::size_t bytes() const;

 private:
  const Scene& scene_;
  std::vector<Wrench> chunk_tool_wrench_;  // per chunk of slot blocks and tool
  std::vector<Vec3> chunk_wall_force_;     // per chunk and wall
  std::vector<std::int64_t> chunk_claim_;  // the pass in which a chunk was claimed
  std::int64_t chunk_pass_ = 0;
  std::size_t chunks_ = 0;       // this step's chunk count (0: nothing to do)
  std::int64_t overflow_ = -1;  // the lowest particle with too many contacts, or -1
  std::vector<ContactStats> thread_stats_;  // per thread
  std::vector<Wrench> tool_wrench_;
  std::vector<Vec3> wall_force_;
  void sum_chunks(std::size_t C);
  template <bool Fast>
  void run_chunks(State& s, const ToolGeometry& tools, Vec3* force, int t, int T, double* busy,
                  Vec3* torque, const std::uint8_t* ghost, const ChunkWait* wait);
  bool fast_ = true;
  bool triangle_lanes_ = triangles_within_lanes_available();
};

}  // namespace dem
