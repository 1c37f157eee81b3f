// The step: broad phase (when due or when the guard fires), narrow phase and forces for
// particle pairs, wall and mesh contacts, integration. The engine holds only workspace and
// the last step's outputs; everything that evolves is in State.
#pragma once

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "cosim/timer.hpp"
#include "dem/boundary_contacts.hpp"
#include "dem/broad_phase.hpp"
#include "dem/close_pairs.hpp"
#include "dem/engine_options.hpp"
#include "dem/engine_types.hpp"
#include "dem/far_movers.hpp"
#include "dem/pair_blocks.hpp"
#include "dem/pair_kernel.hpp"
#include "dem/rotation.hpp"
#include "dem/scene.hpp"
#include "dem/sleepers.hpp"
#include "dem/state.hpp"
#include "dem/thread_team.hpp"
#include "dem/tool_geometry.hpp"

namespace dem {

// The engine's parts (each in its own header): the tools' world geometry, the broad phase, the
// far-mover guard, close pairs, pair blocks, the sleepers with the region of interest, and the
// boundary (wall and mesh) contacts. The step runs them in stages: prepare (geometry, region,
// broad phase or guard), pair forces, boundary forces, integration.
class Engine {
 public:
  explicit Engine(const Scene& scene, const EngineOptions& options = {});

  // Advances one dt. Tool poses are read from s.tool_pose (set them before the call).
  void step(State& s);
  // First stage of step(): world tool geometry and the broad phase if it is due or the guard
  // fires. Idempotent; tests call it to inspect the lists the next narrow phase will use.
  void prepare(State& s);
  // Forces a broad phase now (e.g. after particles were added or moved by hand).
  void rebuild(State& s);
  // Domain decomposition (dem/mpi/, docs/mpi.md): (*ghost)[i] != 0 marks particle i as a copy
  // of another rank's particle, which the caller overwrites after every step. A ghost has no
  // wall or tool contact (no wrench, wall force or boundary stat; its owner has them), and the
  // engine builds no lists on its own: the caller rebuilds on every rank at the same step, and
  // prepare() throws std::logic_error if lists are due. nullptr (the default): every particle
  // is this process's own, today's engine. The vector must outlive its use and match s.
  void set_ghosts(const std::vector<std::uint8_t>* ghost) { ghost_ = ghost; }

  const Scene& scene() const { return scene_; }
  const EngineOptions& options() const { return options_; }
  const std::vector<Wrench>& tool_wrenches() const { return boundary_.tool_wrenches(); }
  const std::vector<Vec3>& wall_forces() const { return boundary_.wall_forces(); }  // on each wall
  const ContactStats& contact_stats() const { return stats_; }  // of the last step
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
  std::int64_t sleeping() const { return sleepers_.sleeping(); }
  // Sleepers woken and particles fallen asleep over every step this engine made (repeated
  // steps included): how much the sleeping set churns.
  std::int64_t woke_total() const { return sleepers_.woke_total(); }
  std::int64_t fell_asleep_total() const { return sleepers_.fell_asleep_total(); }
  std::int64_t removed_last() const { return sleepers_.removed_last(); }
  // Steps at which the guard's bound fired but its far-mover check found the lists still
  // complete, so no broad phase ran (scene.guard: rebuild; docs/dem.md "The guard").
  std::int64_t guard_cleared() const { return guard_.cleared(); }
  // Steps this engine made in one parallel region (EngineOptions::one_region; the others ran a
  // region per stage: the rotating model, pair_schedule ranges, or the option off).
  std::int64_t one_region_steps() const { return one_region_steps_; }
  // The step's own threads (scene.thread_wait: yield) when a step ran on them, else nullptr.
  const ThreadTeam* own_threads() const { return team_.get(); }
  // Close pairs (EngineOptions::close_margin): how often they were listed, and the share of the half
  // list's candidates the last listing kept (0 if never listed).
  std::int64_t close_builds() const { return close_.builds(); }
  double close_share() const { return close_.share(); }
  bool close_used() const { return close_.use(); }  // false: the last listing kept too many
  // Pair blocks (EngineOptions::pair_schedule blocks): the first row of each block and the end, as made
  // for the lists of the last step (empty with ranges).
  const std::vector<std::size_t>& pair_block_starts() const { return blocks_.start(); }
  // The broad phase's own stages (grid, sort, permute, ...): where section broad_phase goes.
  const cosim::Timer& broad_phase_stages() const { return broad_.stages(); }
  cosim::Timer& broad_phase_stages() { return broad_.stages(); }
  const BroadPhase& broad_phase() const { return broad_; }

  // For tests and diagnostics: contacts with positive overlap found through the candidate
  // lists at the current positions (particle ids, i < j) and mesh contacts after feature
  // selection (particle id, tool, contact key).
  std::vector<std::pair<std::int64_t, std::int64_t>> particle_contacts(const State& s) const;
  using MeshContact = BoundaryContacts::MeshContact;
  std::vector<MeshContact> mesh_contacts(const State& s);

 private:
  void choose_threads(const State& s);
  void build_lists(State& s);  // region, threads, broad phase
  // Pair forces: the threads' row ranges of equal work, then the rows by pair blocks or ranges.
  void pair_forces(State& s);
  void rotating_pair_forces(State& s);  // Scene::rotation rotating: dem/rotation.hpp
  template <bool Sleep>
  void pair_forces_impl(State& s);
  void split_pair_work(const State& s);
  detail::Kernel pair_kernel() const;
  detail::PairRows pair_rows_of(State& s);
  template <bool Sleep>
  void pair_forces_blocks(State& s, const detail::PairRows& rows, const detail::PairSleep& rules);
  // The pair blocks in parts: the pass (one thread, before), each thread's blocks (inside a
  // region), and the integration's ranges from the blocks' owners (all, or thread t's).
  struct BlockPass;
  BlockPass begin_pair_blocks(State& s, const detail::PairRows& rows, const detail::PairSleep& rules);
  template <bool Sleep>
  void pair_blocks_thread(State& s, const BlockPass& pass, int t, int T);
  void owner_split(const BlockPass& pass, int T, std::size_t* out) const;
  void owner_range(const BlockPass& pass, int T, int t, std::size_t* out) const;
  // BoundaryContacts::ChunkWait's function (ctx: the BlockPass).
  static double wait_for_blocks(const void* ctx, std::size_t lo, std::size_t hi);
  // The step after prepare() in one parallel region (EngineOptions::one_region).
  template <bool Sleep>
  void step_one_region(State& s);
  template <bool Sleep>
  void pair_forces_ranges(State& s, const detail::PairRows& rows, const detail::PairSleep& rules);
  template <bool Sleep>
  void start_forces(const State& s, std::size_t i0, std::size_t i1);
  void sum_contact_stats();
  // Integration: semi-implicit Euler of the awake particles, sleeping rules, and the tallies
  // the guard and close pairs read at the next step.
  struct StepTally;
  struct IntegrationPlan;
  void integrate(State& s);
  template <bool Sleep>
  void integrate_impl(State& s);
  template <bool Sleep>
  IntegrationPlan begin_integration(State& s);  // before the threads
  void end_integration(State& s, StepTally& total, const IntegrationPlan& plan);  // after
  template <bool Sleep>
  void integrate_walk_thread(State& s, std::size_t a0, std::size_t a1, bool keep, bool renote,
                             StepTally& total, int t);
  void integrate_listed_thread(State& s, StepTally& total, int t, int T);
  template <bool Sleep>
  void integrate_range(State& s, std::size_t a0, std::size_t a1, bool keep, bool renote,
                       StepTally& my, Sleepers::ThreadNotes& notes, const std::int32_t* list,
                       int t);
  void integrate_listed(State& s, StepTally& total);  // with the awake list
  // Inside a step's parallel region: every thread waits for all (the engine's own team's
  // barrier where it runs the region, else OpenMP's).
  void region_barrier(int t);
  void finish_step(State& s, const StepTally& total, int lists, bool close);
  void add_busy(std::size_t section, int t, double seconds) {
    busy_[section * static_cast<std::size_t>(max_threads_) + static_cast<std::size_t>(t)] += seconds;
  }
  double* busy_row(std::size_t section) {
    return busy_.data() + section * static_cast<std::size_t>(max_threads_);
  }

  const Scene& scene_;
  EngineOptions options_;
  int threads_ = 1;  // used by the current step: scene.threads capped by the scene size
  int max_threads_ = 1;
  ToolGeometry tools_;
  BroadPhase broad_;
  FarMoverGuard guard_;
  ClosePairs close_;
  PairBlocks blocks_;
  Sleepers sleepers_;
  BoundaryContacts boundary_;
  const std::vector<std::uint8_t>* ghost_ = nullptr;  // set_ghosts
  Rotation rotation_;  // the rotating model's torques (unused by the translating model)
  std::vector<Vec3> force_;
  // This step's awake list (Sleepers::awake) when EngineOptions::awake_list is on, else nullptr.
  const std::vector<std::int32_t>* awake_now_ = nullptr;
  std::vector<std::vector<detail::PairRemote>> remote_;  // per thread
  std::vector<std::size_t> bounds_;  // particle ranges of the threads in pair_forces
  std::vector<std::size_t> split_;   // and the ranges the integration gives them (T + 1)
  std::vector<ContactStats> thread_stats_;  // per thread, pair forces
  std::int64_t one_region_steps_ = 0;
  // The step's own threads (scene.thread_wait: yield, more than 1 thread; made at the first
  // step that needs them), and the team running the current region (nullptr: OpenMP's).
  std::unique_ptr<ThreadTeam> team_;
  ThreadTeam* region_team_ = nullptr;
  // step_one_region: when each thread left its boundary chunks, then its pair blocks (2 T).
  std::vector<double> region_marks_;
  // thread_busy(): section * max_threads_ + t, for the three sections with parallel loops.
  std::vector<double> busy_;
  ContactStats stats_;
  Timing timing_ = make_timing();
};

// "Close pairs: listed N times in S steps, ..." for the end-of-run notes (empty when
// performance.close_margin is 0).
std::string close_pairs_summary(const Engine& engine, long long steps);
// "Sleeping: P % of particle-steps asleep, N asleep at the end; woke W, fell asleep F (w and f
// per step)" for the end-of-run notes (empty when scene.sleep is off).
std::string sleeping_summary(const Engine& engine, double asleep_share, long long steps);

// Kinetic energy of all particles.
double kinetic_energy(const State& s);

// The payload of a tool: the mass of the particles whose centres lie in the box that bounds
// the tool's mesh in its own frame (for a bucket: its cavity and a shell-thin margin around
// it), at the given pose.
double payload_mass(const State& s, const Mesh& mesh, const ToolPose& pose);

}  // namespace dem
