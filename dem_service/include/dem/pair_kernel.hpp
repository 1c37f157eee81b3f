// The pair forces of a range of rows of the half list, all particles awake: the engine's hot
// loop. Two implementations make the same decisions and the same IEEE operations in the same
// order, so their results are equal bit for bit: a scalar one (one candidate at a time, the
// inline functions of contact_law.hpp) and, where the processor has AVX-512, one that takes 8
// candidates of a row at a time (screen and contact force without branches, the forces summed
// in pair order afterwards). The engine is built with -ffp-contract=off, so neither fuses.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "dem/contact_law.hpp"
#include "dem/vec3.hpp"

namespace dem::detail {

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
  Vec3* force = nullptr;                  // per particle, accumulated
  ContactLaw law;
  double dt = 0;
};

struct PairRowStats {
  std::int64_t contacts = 0;     // pairs that carried a force
  double max_overlap = 0;        // m
  double max_overlap_ratio = 0;  // overlap / smaller radius
};

// Rows i in [a0, a1): force[i] gains the sum of its pairs' forces (in pair order), each
// partner j < a1 loses its pair's force directly, a partner j >= a1 is appended to `remote`
// (in pair order). Springs of active pairs advance; springs of pairs out of contact are
// cleared. `vector` asks for the AVX-512 version (used only if pair_rows_vector_available()).
void pair_rows(const PairRows& p, std::size_t a0, std::size_t a1, std::vector<PairRemote>& remote,
               PairRowStats& stats, bool vector);

bool pair_rows_vector_available();

}  // namespace dem::detail
