#include "dem/engine_options.hpp"

#include "dem/scene.hpp"

#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

namespace dem {
namespace {

// A vector-or-scalar switch from the environment variable `name` (unset: left as it is), any
// other value refused with the variable, the two values and what vector means.
void vector_or_scalar(const char* name, const char* vector_means, bool& vector) {
  const char* v = std::getenv(name);
  if (!v) return;
  if (std::strcmp(v, "vector") == 0)
    vector = true;
  else if (std::strcmp(v, "scalar") == 0)
    vector = false;
  else
    throw std::invalid_argument(std::string("environment ") + name + "=" + v +
                                ": use vector (the default: " + vector_means +
                                ") or scalar, or unset it");
}

}  // namespace

EngineOptions EngineOptions::from_environment() {
  EngineOptions o;
  if (const char* v = std::getenv("DEM_PAIR_KERNEL")) {
    if (std::strcmp(v, "vector") == 0)
      o.pair_kernel = PairKernel::vector;
    else if (std::strcmp(v, "scalar") == 0)
      o.pair_kernel = PairKernel::scalar;
    else if (std::strcmp(v, "avx2") == 0)
      o.pair_kernel = PairKernel::avx2;
    else
      throw std::invalid_argument(std::string("environment DEM_PAIR_KERNEL=") + v +
                                  ": use vector (the default), avx2 or scalar, or unset it");
  }
  if (const char* v = std::getenv("DEM_PAIR_CHUNKS")) {
    if (std::strcmp(v, "branch-free") == 0)
      o.pair_chunks = PairChunks::branch_free;
    else if (std::strcmp(v, "branching") == 0)
      o.pair_chunks = PairChunks::branching;
    else
      throw std::invalid_argument(std::string("environment DEM_PAIR_CHUNKS=") + v +
                                  ": use branch-free or branching, or unset it (the processor "
                                  "picks)");
  }
  if (const char* v = std::getenv("DEM_PAIR_PASSES")) {
    if (std::strcmp(v, "auto") == 0)
      o.pair_passes = PairPasses::automatic;
    else if (std::strcmp(v, "one") == 0)
      o.pair_passes = PairPasses::one;
    else if (std::strcmp(v, "two") == 0)
      o.pair_passes = PairPasses::two;
    else
      throw std::invalid_argument(std::string("environment DEM_PAIR_PASSES=") + v +
                                  ": use auto (the default: two passes for scenes of up to " +
                                  std::to_string(kScreenedMaxParticles) +
                                  " particles), one or two, or unset it");
  }
  vector_or_scalar("DEM_ROW_TEST", "AVX-512, else AVX2, where the processor has it",
                   o.vector_row_test);
  vector_or_scalar("DEM_TRIANGLE_TEST",
                   "4 triangles at a time with AVX2 where the processor has it",
                   o.vector_triangle_test);
  return o;
}

}  // namespace dem

namespace dem {

double close_distance(const Scene& scene, const EngineOptions& options) {
  return options.close_margin * scene.r_max();
}

bool close_pairs_on(const Scene& scene, const EngineOptions& options) {
  return options.close_margin > 0 && (!scene.sleep.enabled || scene.sleep.close_pairs);
}

}  // namespace dem
