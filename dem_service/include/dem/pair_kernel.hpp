// The pair forces of a range of rows of the half list, all particles awake: the engine's hot
// loop. Two implementations make the same decisions and the same IEEE operations in the same
// order, so their results are equal bit for bit: a scalar one (one candidate at a time, the
// inline functions of contact_law.hpp) and, where the processor has AVX-512, one that takes 8
// candidates at a time (8 consecutive pairs of any rows when all are awake, 8 of one row with
// sleepers; screen and contact force without branches, the forces summed in pair order
// afterwards). The engine is built with -ffp-contract=off, so neither fuses.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "dem/contact_law.hpp"
#include "dem/vec3.hpp"

namespace dem::detail {

// Which implementation runs the rows; all four give the same bits. scalar: one candidate at a
// time. vector: the AVX-512 chunk kernel where the processor has it (pair_rows_vector_available),
// else the AVX2 one where it has that (pair_rows_avx2_available), else the scalar loop.
// emulated: the chunk kernel's source with its AVX-512 lane operations emulated in portable C++
// (src/simd512_emulation.hpp), on any processor; slow, for the tests that hold the vector path
// to the scalar loop's bits where CI has no AVX-512. avx2: the screen of every
// candidate, then the contact forces of 4 pairs past it at a time on AVX2
// (src/pair_kernel_avx2.cpp), where available, whatever else the processor has; without AVX2
// the scalar loop.
enum class Kernel { scalar, vector, emulated, avx2 };

// The processor's choice for PairRows::branch_free_chunks: branch-free on AMD, where 512-bit
// divisions are cheap (an AMD EPYC VM: 0.93x of the pair forces branch-free); branching where
// they are dear (an Intel Xeon VM: 0.935x with the branch). docs/performance.md, "Divisions
// where they are dear". EngineOptions::pair_chunks overrides it.
bool branch_free_chunks_default();

// A force on a particle of a later thread's range: applied after the parallel loop, in
// thread order, so the sums do not depend on scheduling.
struct PairRemote {
  std::int32_t j;
  Vec3 f;
};

// The arrays of State the pair forces read and write (raw pointers: the compiler cannot prove
// that writing a spring leaves the vectors' data pointers alone).
struct PairRows {
  const Vec3* x = nullptr;
  const Vec3* u = nullptr;
  const double* radius = nullptr;
  const double* mass = nullptr;
  const std::int32_t* offset = nullptr;   // CSR rows of the half list (i < j)
  const std::int32_t* partner = nullptr;  // j of each pair
  Vec3* spring = nullptr;                 // tangential history of each pair (acts on i)
  // Close pairs (the engine's sub-list of the half list): spring[k] is a copy of the half
  // list's spring_home[spring_index[k]], and both are written, so the half list's springs stay
  // current. All awake only (pair_rows); nullptr: no copy.
  const std::int32_t* spring_index = nullptr;
  Vec3* spring_home = nullptr;
  Vec3* force = nullptr;                  // per particle, accumulated
  // Partners j < direct_end lose their share directly, later ones go to `remote`; 0: the end
  // of the rows (a1). The engine's pair blocks set it to the particle count: a block's
  // partners lie in it or in the next block, which no other thread writes meanwhile.
  std::size_t direct_end = 0;
  ContactLaw law;
  double dt = 0;
  // The vector stream kernel (every particle awake) computes the spring's turn and the friction
  // cap in every chunk without a branch (true), or only in chunks that need them (false). The
  // same bits either way; the default follows the processor (branch_free_chunks_default()).
  bool branch_free_chunks = branch_free_chunks_default();
  // The vector stream kernel over the half list (not close pairs) in two passes: the screen of 8
  // consecutive pairs at a time queues those not surely apart (in pair order), and the contact
  // force runs on 8 queued pairs at a time, so that its lanes are not spent on pairs apart
  // (most candidates of a bed at skin 0.3-0.5). The same bits either way.
  bool screened = false;
  // With screened: the rows with sleeping rules also queue their pairs past the screen and run
  // their contact forces 8 queued pairs at a time, instead of a chunk per row. The same bits.
  bool queued_rows = true;
  // Kernel::avx2: the pairs screened before their contact forces run (4 to 256; a row longer
  // than this runs through the scalar loop alone). Smaller values are for the tests.
  int queue_pairs = 256;
};

struct PairRowStats {
  std::int64_t contacts = 0;     // pairs that carried a force
  double max_overlap = 0;        // m
  double max_overlap_ratio = 0;  // overlap / smaller radius
};

// Rows i in [a0, a1): force[i] gains the sum of its pairs' forces (in pair order), each
// partner j < a1 (or PairRows::direct_end) loses its pair's force directly, a later partner is
// appended to `remote` (in pair order). Springs of active pairs advance; springs of pairs out
// of contact are cleared. `kernel` picks the implementation (the same bits).
void pair_rows(const PairRows& p, std::size_t a0, std::size_t a1, std::vector<PairRemote>& remote,
               PairRowStats& stats, Kernel kernel);

// Sleeping (Scene::sleep): the rules of the pair loop with sleepers. A pair of two sleepers
// computes nothing (its spring stays); awake against asleep, the force acts on the awake
// particle only, and the sleeper wakes when the contact ends with history or the partner is
// faster than the wake speed. Awake pairs get exactly what pair_rows gives them.
struct PairSleep {
  const std::int32_t* rest = nullptr;  // State::rest_steps: asleep when >= steps
  std::int32_t steps = 0;
  double wake_speed2 = 0;              // (scene.sleep.wake_speed, by default speed)^2
  // Rows of sleepers are read only if awake_partners[i] > 0 (the number of awake partners in
  // row i); nullptr: every row is read.
  const std::int32_t* awake_partners = nullptr;
  std::uint8_t* wake = nullptr;  // set to 1 for a sleeper to wake in [a0, a1)
  std::vector<std::int32_t>* remote_wake = nullptr;  // sleepers to wake beyond a1
  std::vector<std::int32_t>* woken = nullptr;  // those of [a0, a1) woken, each once (or nullptr)
};
void pair_rows_sleep(const PairRows& p, const PairSleep& sleep, std::size_t a0, std::size_t a1,
                     std::vector<PairRemote>& remote, PairRowStats& stats, Kernel kernel);

bool pair_rows_vector_available();
// Whether this build (GCC on x86-64) and processor have the AVX2 kernel (Kernel::avx2).
bool pair_rows_avx2_available();

}  // namespace dem::detail
