// How the engine computes, where the choice changes speed but never a result (every option
// below gives the same bits; tests compare whole runs both ways; pair_schedule ranges only for
// one thread count). Not part of the physical
// Scene: the apps (dem_run, dem_service, the benches) fill it once and hand it to each Engine.
#pragma once

#include <cstddef>

namespace dem {

struct Scene;

// How the threads share the pair forces (EngineOptions::pair_schedule).
enum class PairSchedule { blocks, ranges };

struct EngineOptions {
  // The config's performance: section (docs/dem.md#performance), read with the scene
  // (dem::load_config, RunConfig::performance) and copied in by the apps (with_config).
  // Close pairs: the pair forces take only the candidates within close_margin * r_max of
  // contact (or of a fast particle), re-listed when the slow particles may have closed the
  // margin; the results are the same bits as with every candidate. 0: every candidate, every
  // step. With sleeping on, used only if scene.sleep.close_pairs (close_pairs_on()).
  double close_margin = 0.0;
  // blocks: the rows in blocks whose partners lie in the block or the next, each run by the
  // thread that claims it first on its walk (an odd block once the even ones beside it are
  // done; detail::pair_block_walk); the sums do not depend
  // on the thread count. ranges: one contiguous range of equal work per thread, partners in a
  // later range applied after the loop (the sums depend on the thread count).
  PairSchedule pair_schedule = PairSchedule::blocks;
  // Fewer particles per thread than this and the step uses fewer threads: for small scenes
  // the barriers cost more than the work (and a lot more on a loaded machine).
  int min_particles_per_thread = 2000;

  // The pair forces: the AVX-512 kernel where the processor has it, else the AVX2 one where it
  // has that (vector), or the scalar loop everywhere. Kept: the scalar loop is the reference the
  // vector kernels' bit-equality tests compare against, and bench/dem/kernel_ab.sh times one
  // against the other.
  // emulated: the vector kernel's source with its lanes emulated in portable code (any
  // processor, several times slower): for the tests that hold the vector path to the scalar
  // loop's bits where the processor has no AVX-512.
  // avx2: the contact forces of 4 screened pairs at a time on AVX2 (what `vector` runs on a
  // processor without AVX-512; detail::Kernel::avx2), chosen explicitly for tests and
  // benchmarks; the scalar loop where the processor lacks AVX2.
  enum class PairKernel { vector, scalar, emulated, avx2 };
  PairKernel pair_kernel = PairKernel::vector;
  // The vector stream kernel's chunks: without a branch for the spring's turn and the friction
  // cap (branch-free), or only where a lane needs them (branching). The processor's default is
  // branch-free on AMD, branching elsewhere (docs/performance.md, "Divisions where they are
  // dear"). Kept: which is faster depends on the processor, and the tests cover both.
  enum class PairChunks { processor, branch_free, branching };
  PairChunks pair_chunks = PairChunks::processor;
  // The broad phase's distance test: 8 candidates at a time with AVX-512 where the processor
  // has it, or the scalar test everywhere. Kept: the broad-phase test compares whole runs.
  bool vector_row_test = true;
  // The broad phase's history: a row whose new row lists the same partners copies its springs
  // in place; off, every held spring is looked up in its new row. Kept: the broad-phase test
  // compares whole runs both ways (dem_BroadPhase.RunIsBitIdenticalWithHistoryCopiedOrLookedUp).
  bool history_same_rows = true;
  // The boundary contacts' fast path (fetching ahead, a resting contact's springs copied, no
  // zeroing per particle; BoundaryContacts::use_fast_path). Always on in the apps; off only for
  // the tests that hold it to the code before it (dem_BoundaryFast.*).
  bool boundary_fast = true;
  // The fast path's triangle test: a sphere's candidate triangles 4 at a time with AVX2 where
  // the processor has it (dem::triangles_within, the same decisions as the closest point), or
  // one at a time. Kept: the tests compare whole runs both ways (dem_BoundaryFast.*).
  bool vector_triangle_test = true;
  // Sleeping's shortcuts: the pair loop reads a sleeper's row only when it holds an awake
  // partner, and the integration skips the tool test for a block of 64 sleepers beyond every
  // tool's neighbourhood. Settled (always on in the apps); kept as switches only for the tests
  // that prove each shortcut changes no bit (dem_Sleep.SkippingTheRowsOfSleepersChangesNoBit,
  // dem_Sleep.SkippingBlocksOfSleepersFarFromToolsChangesNoBit), which need the long way to
  // compare against.
  bool sleeper_row_skip = true;
  bool sleeper_blocks = true;
  // The awake list (Sleepers::awake): the pair loop starts the forces of the awake particles
  // only, and the integration visits only them and the sleepers a wake test needs, instead of
  // walking the whole bed. Always on in the apps; off only for the tests that hold it to the
  // walk over every particle (dem_Sleep.AwakeListChangesNoBit).
  bool awake_list = true;
  // A step in one OpenMP parallel region (pair forces, boundary contacts and integration, with
  // waits and barriers between them) instead of one region per stage: fewer waits for threads to
  // wake (docs/performance.md, "One parallel region per DEM step"). Taken with pair_schedule
  // blocks and the translating model; the broad phase keeps its own regions. Always on in the
  // apps; off only for the tests that hold it to the regions per stage
  // (dem_OneRegion.*).
  bool one_region = true;
  // The vector stream kernel over the half list in one pass, or in two (detail::PairRows::
  // screened): the screen of every candidate, then the contact forces of the pairs past it, 8 at
  // a time. automatic: two passes for scenes of at most kScreenedMaxParticles particles, whose
  // arrays stay in the caches (the main job's 10k pile: 0.95x of the step), one pass above
  // (the 150k bed: two passes 1.02-1.06x); docs/performance.md, "The screened stream". The same
  // bits every way; the tests run both (dem_PairKernel.*).
  enum class PairPasses { automatic, one, two };
  PairPasses pair_passes = PairPasses::automatic;
  static constexpr std::size_t kScreenedMaxParticles = 50000;
  // With two passes, the rows with sleeping rules (a sleeper's row with awake partners, an awake
  // row with sleeping partners) queue their pairs too (detail::PairRows::queued_rows) instead of
  // a chunk per row; docs/performance.md, "The screened stream". The same bits; off only to
  // measure against.
  bool queued_rows = true;

  // The apps' spelling, from the environment: DEM_PAIR_KERNEL (vector | scalar),
  // DEM_PAIR_CHUNKS (branch-free | branching) and DEM_PAIR_PASSES (auto | one | two);
  // unset: the defaults. Throws std::invalid_argument naming the variable and its values for
  // anything else.
  static EngineOptions from_environment();
  // These options with the config's performance: section's (close_margin, pair_schedule,
  // min_particles_per_thread) in place of theirs.
  EngineOptions with_config(const EngineOptions& performance) const {
    EngineOptions o = *this;
    o.close_margin = performance.close_margin;
    o.pair_schedule = performance.pair_schedule;
    o.min_particles_per_thread = performance.min_particles_per_thread;
    return o;
  }
};

// The distance close pairs are listed within (close_margin * r_max), and whether they are used.
double close_distance(const Scene& scene, const EngineOptions& options);
bool close_pairs_on(const Scene& scene, const EngineOptions& options);

}  // namespace dem
