// The chunk kernel of pair_kernel.cpp compiled with its AVX-512 intrinsics emulated lane by lane
// in portable C++ (simd512_emulation.hpp): the same source, the same lane operations in the same
// order, on any processor. Its bit-equality with the scalar loop is what the dem_PairKernel
// tests check everywhere CI runs (Kernel::emulated); on a processor with AVX-512 they also
// check the real kernel.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "dem/pair_kernel.hpp"
#include "pair_kernel_parts.hpp"
#include "simd512_emulation.hpp"

namespace dem::detail {
namespace {

using namespace emulated;
#define DEM_AVX512
#include "pair_kernel_chunks.inc"
#undef DEM_AVX512

}  // namespace

void pair_rows_emulated(const PairRows& p, const PairSleep* sleep, std::size_t a0, std::size_t a1,
                        std::size_t direct, std::vector<PairRemote>& remote,
                        PairRowStats& stats) {
  if (sleep)
    run_chunk_kernel<true>(p, *sleep, a0, a1, direct, remote, stats);
  else
    run_chunk_kernel<false>(p, PairSleep{}, a0, a1, direct, remote, stats);
}

}  // namespace dem::detail
