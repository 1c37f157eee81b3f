// The step: broad phase (when due or when the guard fires), narrow phase and forces for
// particle pairs, wall and mesh contacts, integration. The engine holds only workspace and
// the last step's outputs; everything that evolves is in State.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "cosim/timer.hpp"
#include "dem/broad_phase.hpp"
#include "dem/pair_kernel.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem {

// The run cannot continue: NaN, runaway speed, guard violation in strict mode, too many
// boundary contacts. The message names the step, time, particle and the fix.
struct SimulationError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The soil's wrench on a tool as the contact loops sum it, in the hot-loop Vec3. It stays inside
// the engine: outside it is a cosim::Wrench (dem/coupling.hpp converts, with the point).
struct Wrench {
  Vec3 force;   // on the tool, ground frame
  Vec3 torque;  // about the tool's reference point, ground frame
};

// What the last step's force evaluation saw: contacts that carried a force and the deepest
// overlap, absolute and as a fraction of the smaller radius (a stiffness/dt sanity check).
struct ContactStats {
  std::int64_t particle_contacts = 0;
  std::int64_t boundary_contacts = 0;  // walls and tool features
  double max_overlap = 0;              // m
  double max_overlap_ratio = 0;        // overlap / smaller radius
};

// Wall-clock seconds per stage, LAMMPS style: the rows of the timing table, the `/timing`
// attributes of the output file and dem_service's `seconds_<section>` diagnostics.
using Timing = cosim::Timer;
namespace section {
enum : std::size_t {
  broad_phase,    // tool geometry for the lists and the broad phase
  pair_forces,    // narrow phase + contact forces between particles
  mesh_contacts,  // walls and tool meshes (and the tools' world geometry)
  integration,
  output,         // filled by the caller that writes files
};
}  // namespace section
Timing make_timing();  // the sections above, named as in the output

class Engine {
 public:
  explicit Engine(const Scene& scene);

  // Advances one dt. Tool poses are read from s.tool_pose (set them before the call).
  void step(State& s);
  // First stage of step(): world tool geometry and the broad phase if it is due or the guard
  // fires. Idempotent; tests call it to inspect the lists the next narrow phase will use.
  void prepare(State& s);
  // Forces a broad phase now (e.g. after particles were added or moved by hand).
  void rebuild(State& s);

  const Scene& scene() const { return scene_; }
  const std::vector<Wrench>& tool_wrenches() const { return tool_wrench_; }
  const std::vector<Vec3>& wall_forces() const { return wall_force_; }  // on each wall
  const ContactStats& contact_stats() const { return stats_; }          // of the last step
  Timing& timing() { return timing_; }
  const Timing& timing() const { return timing_; }
  int threads() const { return threads_; }  // threads of the last step
  // Seconds thread t spent working in a section's parallel loops (pair_forces, mesh_contacts,
  // integration), its waits for other threads left out; summed over the run like timing().
  // Their sum over the threads against threads x the section's wall time is the share of the
  // cores the section used: below 1 where the work was not split evenly.
  double thread_busy(std::size_t section, int t) const;
  void reset_thread_busy();  // with timing().reset(), where a caller starts the tables anew
  // Bytes of workspace the engine and its broad phase keep between steps (not State).
  std::size_t workspace_bytes() const;
  // Particles asleep after the last step (scene.sleep; 0 when sleeping is disabled) and
  // particles removed by the region of interest in the last prepare()/rebuild().
  std::int64_t sleeping() const { return sleeping_; }
  // Sleepers woken and particles fallen asleep over every step this engine made (repeated
  // steps included): how much the sleeping set churns.
  std::int64_t woke_total() const { return woke_total_; }
  std::int64_t fell_asleep_total() const { return fell_asleep_total_; }
  std::int64_t removed_last() const { return removed_last_; }
  // Steps at which the guard's bound fired but its far-mover check found the lists still
  // complete, so no broad phase ran (scene.guard: rebuild; docs/dem.md "The guard").
  std::int64_t guard_cleared() const { return guard_cleared_; }
  // Close pairs (Scene::close_margin): how often they were listed, and the share of the half
  // list's candidates the last listing kept (0 if never listed).
  std::int64_t close_builds() const { return close_builds_; }
  double close_share() const { return close_share_; }
  bool close_used() const { return close_.use; }  // false: the last listing kept too many
  // Pair blocks (Scene::pair_schedule blocks): the first row of each block and the end, as made
  // for the lists of the last step (empty with ranges).
  const std::vector<std::size_t>& pair_block_starts() const { return blocks_.start; }
  // The broad phase's own stages (grid, sort, permute, ...): where section broad_phase goes.
  const cosim::Timer& broad_phase_stages() const { return broad_.stages(); }
  cosim::Timer& broad_phase_stages() { return broad_.stages(); }

  // For tests and diagnostics: contacts with positive overlap found through the candidate
  // lists at the current positions (particle ids, i < j) and mesh contacts after feature
  // selection (particle id, tool, contact key).
  std::vector<std::pair<std::int64_t, std::int64_t>> particle_contacts(const State& s) const;
  struct MeshContact {
    std::int64_t particle;
    int tool;
    std::uint64_t key;
    Vec3 point;
  };
  std::vector<MeshContact> mesh_contacts(const State& s);

 private:
  void update_tool_geometry(const State& s);
  void choose_threads(const State& s);
  bool guard_fires(const State& s, double* moved);
  double tool_move(const State& s, std::size_t m) const;
  double tool_window(const State& s, std::size_t m) const;
  // The guard's second look (scene.guard: rebuild) when its bound fires: true when the lists
  // still hold every contact because only a few particles moved more than half the skin and
  // none of them has come near a particle, wall or tool it is not listed with.
  bool far_movers_clear(const State& s);
  void find_far_movers(const State& s);
  // The largest squared displacement and speed of the particles that moved at most half the
  // skin (the others), and the largest squared speed of all.
  struct FarTally {
    double near2 = 0, near_u2 = 0, u2 = 0;
    void merge(const FarTally& o);
  };
  struct FarLimits {
    double d2, u2;  // far beyond either (squared displacement, squared speed)
  };
  FarLimits far_limits() const;
  static void note_far_mover(std::vector<std::int32_t>& far, FarTally& tally, std::size_t i,
                             double d2, double ui2, const FarLimits& limits);
  void finish_far_movers(const State& s, int lists, const FarTally& tally);
  // Close pairs: the candidates of the half list within Scene::close_distance() of contact,
  // and every candidate of a particle faster than `fast` when they were listed. A pair left
  // out was farther apart than the margin, so it cannot act (or hold history) before the slow
  // particles' two largest displacements since then and their step window add up to the
  // margin (checked before each step's pair forces, tallied by the integration).
  struct ClosePairs {
    std::vector<std::int32_t> offset, partner, index;  // CSR rows; index: the pair in the half list
    std::vector<Vec3> spring;  // copies of their springs, in their order (both are written)
    std::vector<std::uint8_t> keep, fast;              // per candidate; per particle
    std::vector<Vec3> x_at;                            // positions when listed
    std::vector<std::int64_t> thread_base;
    const State* state = nullptr;                      // the lists they were taken from
    std::size_t size = 0, candidates = 0;
    std::int64_t rebuilds = -1, built_at = -1;
    std::int64_t step = -1;  // the state's step that the copies and the tally are of
    double d1 = 0, d2 = 0, u2 = 0;  // slow particles since: two largest squared displacements, speed^2
    bool use = false;  // false: they kept nearly every candidate, the half list is read instead
  };
  // Pair blocks (Scene::pair_schedule blocks): consecutive row ranges of the half list, every
  // partner of block k's rows in block k or k + 1, made from the lists at each broad phase. An
  // even block sets up its own and the next block's forces and runs its rows; an odd block runs
  // once the two even blocks beside it are done. Each thread walks all blocks in its own order
  // (detail::pair_block_walk) and runs those it claims first, so a thread keeps the same part
  // of the bed from step to step and a slowed thread runs fewer blocks.
  struct PairBlocks {
    std::vector<std::size_t> start;  // K + 1 boundaries
    std::vector<std::int64_t> done;   // the pass in which block k's rows were done
    std::vector<std::int64_t> claim;  // the pass in which block k was claimed by a thread
    std::vector<int> owner;            // the thread that ran block k in the last pass
    std::int64_t pass = 0;
    const State* state = nullptr;  // the lists they were made for
    std::size_t size = 0, candidates = 0;
    std::int64_t rebuilds = -1, built_at = -1;
  };
  void make_pair_blocks(const State& s);
  bool close_pairs_hold(const State& s) const;
  void list_close_pairs(State& s);
  void pair_forces(State& s);
  template <bool Sleep>
  void pair_forces_impl(State& s);
  void count_awake_partners(const State& s);
  void update_awake_partners(const State& s);
  template <bool Sleep>
  void start_forces(const State& s, std::size_t i0, std::size_t i1);
  void boundary_forces(State& s);
  void integrate(State& s);
  template <bool Sleep>
  void integrate_impl(State& s);
  void remove_outside(State& s);
  void size_sleep_arrays(State& s);

  const Scene& scene_;
  int threads_ = 1;  // used by the current step: scene.threads capped by the scene size
  int max_threads_ = 1;
  BroadPhase broad_;
  std::vector<Vec3> force_;
  std::vector<std::vector<Vec3>> tool_vertices_;  // world frame, current pose
  std::vector<Mat3> tool_rotation_;
  std::vector<Vec3> tool_box_min_, tool_box_max_;  // mesh frame, for scene.sleep.neighbourhood
  std::vector<double> tool_box_radius_;             // farthest box corner from the reference point
  std::vector<std::vector<detail::PairRemote>> remote_;  // per thread
  std::vector<std::size_t> bounds_;  // particle ranges of the threads in pair_forces
  std::vector<std::size_t> split_;   // and the ranges the integration gives them (T + 1)
  PairBlocks blocks_;
  ClosePairs close_;
  std::int64_t close_builds_ = 0;
  double close_share_ = 0;
  // Sleeping: wake_[i] set by the pair loop when a sleeper is to wake; wakes of particles in
  // another thread's range are queued per thread and applied after the loop.
  std::vector<std::uint8_t> wake_;
  std::vector<std::vector<std::int32_t>> remote_wake_;  // per thread
  std::vector<std::uint8_t> remove_;                    // region of interest workspace
  // Sleeping: the awake partners of each row (State::pair_row), so that the pair loop reads a
  // sleeper's row only when it holds one. Counted once after a broad phase and kept up to date
  // by the integration from the particles that woke or fell asleep in its step (a few dozen per
  // step in the paper's pile, against 28,000 awake ones that would mark rows every step). Valid
  // for the state, size, lists and step it was kept for; counted again otherwise.
  struct AwakePartners {
    std::vector<std::int32_t> count;
    std::vector<std::int32_t> woke, fell;  // this step's transitions (the integration's)
    const State* state = nullptr;
    std::size_t size = 0, pairs = 0;
    std::int64_t rebuilds = -1, step = -1;
    bool holds(const State& s, std::int64_t at_step) const;  // kept for s at this step
    void add(const State& s, std::int32_t j, std::int32_t delta);
  };
  AwakePartners awake_partners_;
  std::int64_t sleeping_ = 0;
  std::int64_t woke_total_ = 0, fell_asleep_total_ = 0;
  // Sleeping: what the sleepers add to the guard's tallies (two largest displacements, the far
  // movers' tally and list). A sleeper does not move, so its displacement since the broad phase
  // is the one it fell asleep with (0 for one asleep at the broad phase): noted once, when it
  // falls asleep, instead of every step. Woken ones stay in it until the next broad phase (an
  // upper bound: the guard may rebuild earlier, never later). Valid for the state, size,
  // broad phase and step it was kept for; else the integration notes every sleeper again.
  struct SleeperTally {
    double d1 = 0, d2 = 0;
    FarTally tally;
    std::vector<std::int32_t> far;
    // The box around the sleepers of each block of kSleepBlock particles (by index), grown as
    // particles fall asleep, made again after each broad phase (it reorders them): a block
    // whose box is beyond every tool's neighbourhood needs no per-sleeper test of it.
    std::vector<Vec3> box_lo, box_hi;
    std::vector<std::int32_t> fell_asleep;  // this step's, to grow the boxes after the loop
    const State* state = nullptr;
    std::size_t size = 0;
    std::int64_t rebuilds = -1, step = -1;
    void clear();
  };
  SleeperTally sleepers_;
  static constexpr std::size_t kSleepBlock = 64;
  // Far movers: particles that moved more than half the skin since the last broad phase, in
  // ascending order (at most kMaxFarMovers, else far_overflow_), with the largest displacement
  // of all the others and the largest speed |u| of any particle. The integration collects them
  // for the state after its step (far_step_, far_state_); find_far_movers() for any other.
  static constexpr std::size_t kMaxFarMovers = 1024;
  std::vector<std::int32_t> far_;
  std::vector<std::uint8_t> far_flag_;  // far_movers_clear: 1 for the far movers, else 0
  std::vector<std::vector<std::int32_t>> thread_far_;  // per thread
  bool far_overflow_ = false;
  double near_max_ = 0, near_u_max_ = 0, u_max_ = 0;
  std::int64_t far_step_ = -1;
  const State* far_state_ = nullptr;
  std::size_t far_size_ = 0;
  std::int64_t guard_cleared_ = 0, cleared_at_ = -1;
  std::vector<double> tool_moves_;  // far-mover check: each tool's move since the broad phase
  // Each tool's triangles binned on a grid in the mesh frame (built when the far-mover check
  // first needs it; meshes are rigid): the triangles near a point without a pass over all.
  struct MeshGrid {
    Vec3 lo{};
    double inv_h = 1;
    long nx = 0, ny = 0, nz = 0;
    std::vector<std::int32_t> start, tri;
  };
  std::vector<MeshGrid> mesh_grid_;
  void build_mesh_grids();
  bool unlisted_triangle_near(const State& s, std::size_t e, std::size_t m, double reach) const;
  std::int64_t removed_last_ = 0;
  std::vector<Wrench> chunk_tool_wrench_;  // boundary_forces: per chunk of slot blocks and tool
  std::vector<Vec3> chunk_wall_force_;     // per chunk and wall
  std::vector<std::int64_t> chunk_claim_;  // the pass in which a chunk was claimed
  std::int64_t chunk_pass_ = 0;
  std::vector<ContactStats> thread_stats_, boundary_stats_;  // per thread
  // thread_busy(): section * max_threads_ + t, for the three sections with parallel loops.
  std::vector<double> busy_;
  void add_busy(std::size_t section, int t, double seconds) {
    busy_[section * static_cast<std::size_t>(max_threads_) + static_cast<std::size_t>(t)] += seconds;
  }
  ContactStats stats_;
  std::vector<Wrench> tool_wrench_;
  std::vector<Vec3> wall_force_;
  Timing timing_ = make_timing();
};

// Reads DEM_PAIR_KERNEL from the environment once (unset or "vector": the AVX-512 pair kernel
// where the processor has it; "scalar": the scalar loop; both give the same bits) and throws
// std::invalid_argument naming the variable and its values for anything else. Every Engine
// calls it; dem_run and dem_service call it at start-up so a bad value stops them at once.
void read_pair_kernel_environment();

// "Close pairs: listed N times in S steps, ..." for the end-of-run notes (empty when
// scene.close_margin is 0).
std::string close_pairs_summary(const Engine& engine, long long steps);
// "Sleeping: P % of particle-steps asleep, N asleep at the end; woke W, fell asleep F (w and f
// per step)" for the end-of-run notes (empty when scene.sleep is off).
std::string sleeping_summary(const Engine& engine, double asleep_share, long long steps);

namespace detail {
// Whether the pair loop skips the rows of sleepers that hold no awake partner (the default) or
// scans every row as before; tests compare whole runs both ways.
void use_sleeper_row_skip(bool skip);
// Whether the integration skips the tool-neighbourhood test for whole blocks of sleepers that are
// beyond every tool (the default) or tests every sleeper as before; tests compare both ways.
void use_sleeper_blocks(bool blocks);
// Whether the all-awake pair forces use the AVX-512 kernel where the processor has it (the
// default) or the scalar loop; both give the same bits (dem/pair_kernel.hpp), tests compare.
void use_vector_pairs(bool vector);
// The order in which thread t of T visits K pair blocks (and the boundary chunks): every block
// once, an even block before the odd blocks beside it. Threads 0 .. T-2 walk forward from the
// (even) block near t K / T, wrapping round to block 0; the last thread (T >= 2) walks backward
// from block K - 1. On two threads one walks up from the bottom of the bed and the other down
// from its top.
std::vector<std::int32_t> pair_block_walk(std::int32_t K, int t, int T);
}  // namespace detail

// Kinetic energy of all particles.
double kinetic_energy(const State& s);

// The payload of a tool: the mass of the particles whose centres lie in the box that bounds
// the tool's mesh in its own frame (for a bucket: its cavity and a shell-thin margin around
// it), at the given pose.
double payload_mass(const State& s, const Mesh& mesh, const ToolPose& pose);

}  // namespace dem
