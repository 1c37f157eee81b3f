// Preparing beds: fill regions with particles, let them fall and come to rest under gravity.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "dem/engine.hpp"

namespace dem {

// splitmix64 to a uniform double in [0, 1), advancing `rng`: the same numbers on every platform,
// unlike std:: distributions (fills, random insertion, lab samples).
double uniform01(std::uint64_t& rng);

// A box to fill with `count` particles of one species (index into Scene::species).
struct FillRegion {
  int species = 0;
  Vec3 min, max;
  long long count = 0;
  unsigned long long seed = 1;
};

// Memory a run needs per particle, at least: its State (positions, velocities, contact springs,
// sorted copies) and the engine's workspace and pair lists. The smallest peak resident memory
// per particle measured (docs/performance.md: 1.2M particles, 852 MB; 914-1041 B per particle
// in the paper's scene) is about 710 B; a lower bound, so a run is refused only when it cannot
// fit (docs/dem.md#memory).
constexpr double kBytesPerParticle = 700;

// Bytes this process may still allocate: /proc/meminfo MemAvailable, and when RLIMIT_AS is set,
// that limit minus the address space in use (/proc/self/status VmSize), whichever is smaller.
// `source` (if given) says which bounded it. 0 when unknown (then nothing is refused).
double available_memory_bytes(std::string* source = nullptr);

// Refuses (cosim::config::ConfigError) a scene of `particles` particles in all whose estimated
// memory (kBytesPerParticle each) exceeds what is available, naming `key` (the config key that
// asks for them, e.g. "particles.fill[0].count") and the bytes needed and available.
void check_memory_for_particles(double particles, const std::string& key);

// Samples one radius of species sp with the generator state `rng` (splitmix64).
double sample_radius(const Species& sp, std::uint64_t& rng);

// Fills the region with non-overlapping particles: a jittered lattice of pitch 2 r_max,
// filled from the bottom layer up, radii drawn from the species distribution. Seeded and
// reproducible on every platform (own generator). A region too small for `count` is refused
// with cosim::config::ConfigError naming particles.fill and the fix.
void fill_region(const Scene& scene, const FillRegion& region, State& s);

struct SettleResult {
  double time = 0;             // simulated seconds spent settling
  double ke_per_particle = 0;  // J, at the end
  bool converged = false;
};

// Steps until the kinetic energy per particle is below ke_per_particle (checked every 100
// steps, and only after the highest particle had time to fall to the lowest one), or max_time
// of simulated time passed. Tools hold the pose they have in `s`.
SettleResult settle(Engine& engine, State& s, double ke_per_particle, double max_time,
                    const std::function<void(const SettleResult&)>& progress = {});

}  // namespace dem
