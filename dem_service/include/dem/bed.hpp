// Preparing beds: fill regions with particles, let them fall and come to rest under gravity.
#pragma once

#include <cstdint>
#include <functional>

#include "dem/engine.hpp"

namespace dem {

// A box to fill with `count` particles of one species (index into Scene::species).
struct FillRegion {
  int species = 0;
  Vec3 min, max;
  long long count = 0;
  unsigned long long seed = 1;
};

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
