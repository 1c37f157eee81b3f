// Preparing beds: let filled particles fall and come to rest under gravity.
#pragma once

#include <functional>

#include "dem/engine.hpp"

namespace dem {

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
