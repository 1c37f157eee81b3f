// The DEM on several MPI ranks (docs/mpi.md, "Running the DEM on several ranks"): spatial
// decomposition into slabs with owned particles and ghosts ("newton off": a pair with a ghost is
// computed on both ranks, no reverse communication), the ghosts' positions and velocities sent
// forward after every step, broad phases on every rank at the same step with migration of the
// particles that left their slab (their boundary slots and pair springs travel with them), the
// tools' wrenches and the walls' forces summed in rank order, the particles gathered on rank 0.
//
// This header names no MPI type: the engine's programs include it, and the engine itself
// (Engine, State and the rest of dem/) knows nothing of MPI (tests/layering checks both).
#pragma once

#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "dem/config.hpp"
#include "dem/engine.hpp"
#include "dem/scene.hpp"
#include "dem/state.hpp"

namespace dem::mpi {

// The config's mpi: section (docs/mpi.md). Read by every program; used when more than one rank
// runs.
struct Options {
  std::string decomposition = "slabs";  // slabs: cuts along the longest axis of the particles
  double rebalance = 1.2;  // a broad phase re-cuts when the largest rank's count / the mean exceeds it
};

// Removes root["mpi"] (so the engine's strict config reader never sees it) and validates it:
// unknown keys and bad values throw cosim::config::ConfigError naming the dotted key and the fix.
Options take_options(YAML::Node& root);

// Whether this process was started by mpirun / mpiexec / srun (their environment variables):
// only then does a program call MPI_Init. A program started alone is today's program.
bool launched_by_mpirun();
// The rank count mpirun / srun gives this job (OMPI_COMM_WORLD_SIZE, PMI_SIZE), from the
// environment without MPI; 1 when started alone.
int launched_ranks();

// MPI_Init_thread (funneled: OpenMP threads inside a rank, MPI from the main thread) and
// MPI_Finalize. rank() and size() of MPI_COMM_WORLD.
class Session {
 public:
  Session(int* argc, char*** argv);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }
  // Ends every rank with this exit code (MPI_Abort): after an error on some ranks only, the
  // others would wait for it in their next collective.
  [[noreturn]] static void abort(int code);
  // Max over the ranks of a code (every rank calls it): how a refusal on one rank stops all.
  static int max_over_ranks(int code);

 private:
  int rank_ = 0, size_ = 1;
};

// What N > 1 does not run yet, refused before any step with std::invalid_argument naming the
// key, the reason and the fix (docs/mpi.md lists them).
void check_supported(const RunConfig& rc, const EngineOptions& options, int ranks);

// The halo of one rank, for the end-of-run note and bench/mpi: summed over the steps.
struct HaloStats {
  std::int64_t ghosts = 0;           // ghosts now
  std::int64_t owned = 0;            // owned particles now
  std::int64_t steps = 0;            // forward exchanges made
  std::int64_t bytes_sent = 0;       // by the forward exchanges
  std::int64_t messages_sent = 0;    // by the forward exchanges
  std::int64_t migrations = 0;       // broad phases (each with migration and new ghosts)
  std::int64_t migrated = 0;         // particles that changed rank
  std::int64_t rebalances = 0;       // re-cuts of the slabs
  std::int64_t migration_bytes = 0;  // sent by the broad phases' migration and ghost setup
  double seconds_rebuild = 0;   // wall time of the broad phases with migration and ghost setup
  double seconds_exchange = 0;  // wall time of the forward exchanges and the guard's tally
                                // (waits for the other ranks included)
  std::int64_t ghost_bytes = 0;  // of migration_bytes: the ghost lists' messages
  // seconds_rebuild by part: the count (and re-cut), the migration (records, pack, send,
  // unpack), the ghost lists (select, send, match), the local order and arrays, the engine's
  // broad phase, the springs and the exchange lists.
  double seconds_count = 0, seconds_migrate = 0, seconds_ghosts = 0, seconds_local = 0,
         seconds_broad_phase = 0, seconds_springs = 0;
  // seconds_exchange by part: the forward exchange (pack, send, wait, unpack) and the guard's
  // tally, whose MPI_Allgather is where a rank waits for the slowest (load imbalance).
  double seconds_forward = 0, seconds_tally = 0;
};

// Thrown by Decomposed::step on the ranks whose own step went well when another rank's step
// threw (that rank rethrows its own exception, which names the problem): every rank leaves the
// step together, none waits for the others in a later exchange.
struct OtherRankFailed : SimulationError {
  OtherRankFailed(int rank_, const std::string& what) : SimulationError(what), rank(rank_) {}
  int rank;  // the lowest rank whose step failed
};

// One rank's part of a decomposed run. Every rank calls every member in the same order with the
// same arguments except the state (they are collective).
class Decomposed {
 public:
  // engine: this rank's engine for `scene` (its ghost mask is set here).
  Decomposed(const Scene& scene, Engine& engine, const Options& options);
  ~Decomposed();
  Decomposed(const Decomposed&) = delete;
  Decomposed& operator=(const Decomposed&) = delete;

  // From the whole initial state (every rank loaded the same config, so every rank holds the
  // same `all`): the slabs cut by count, this rank's particles and ghosts in `s` with their lists
  // built. Throws std::invalid_argument for more ranks than broad-phase cells along the axis.
  void start(const State& all, State& s);
  // One step of the whole scene: a broad phase on every rank when one is due (interval, or the
  // guard's bound over all ranks), the engine's step, the ghosts sent forward. When the engine's
  // step throws on some rank (a blow-up), that rank rethrows it after the exchange and the
  // others throw OtherRankFailed: all leave together.
  void step(State& s);

  // The tools' wrenches and the walls' forces of the last step: each rank's sums of its owned
  // particles' contacts, added in rank order on rank 0 and sent to all (the same bits on every
  // run with the same rank count).
  void reduce_boundary(std::vector<Wrench>& tools, std::vector<Vec3>& walls) const;
  // Rank 0: every rank's owned particles (x, v, u, radius, mass, species, id; w and wu with the
  // rotating model), sorted by id, no lists; the others: an empty state. Collective.
  State gather(const State& s) const;
  // Rank 0: the whole scene as one state with its lists and every spring (a broad phase of the
  // gathered particles, the springs from their owners' records): what a checkpoint holds.
  // The others: an empty state. Collective.
  State gather_with_lists(const State& s) const;

  // Repeated steps (dem_service's snapshots): everything besides the State that the next steps
  // read (the ghost mask, the exchange lists, the cuts, the guard's tally over the ranks), kept
  // and put back so that a step repeated from the snapshot gives the same bits. Not collective.
  void save_snapshot();
  void restore_snapshot();
  // The owned particles' count and kinetic energy (translational and, with the rotating model,
  // rotational), summed over the ranks in rank order (collective; every rank gets the sums).
  void totals(const State& s, double& particles, double& kinetic_energy) const;

  int rank() const;
  int ranks() const;
  int axis() const { return axis_; }
  const std::vector<double>& cuts() const { return cuts_; }
  const HaloStats& halo() const { return halo_; }
  // The halo over every rank, one line per rank and the totals (collective; rank 0's is the text).
  std::string halo_summary() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  const Scene& scene_;
  Engine& engine_;
  Options options_;
  int axis_ = 0;
  std::vector<double> cuts_;  // ranks - 1 cut positions along axis_, ascending
  HaloStats halo_;
  bool due_ = true;
  std::unique_ptr<Impl> saved_;  // save_snapshot()
  std::vector<double> saved_cuts_;
  bool saved_due_ = true;

  void rebuild(State& s, bool first);
  // rebuild() after the start: only the particles that change rank travel, the ghost lists send
  // ids for the ghosts the receiver holds already, and the rank's particles are put in the
  // broad phase's order (cell, then id) from the order they are in (docs/mpi.md).
  void rebuild_kept(State& s);
  // The guard's tally over all ranks; failed: this rank's step threw. Returns the lowest rank
  // whose step threw, -1 for none (the same on every rank).
  int tally(State& s, bool failed = false);
};

}  // namespace dem::mpi
