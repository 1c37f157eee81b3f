// Coarse graining (`particles.coarse_grain: s`, docs/soil_models.md "Coarse graining"): the same
// material with grains s times larger. What scales and why:
//   radius            x s      (the lever)
//   density           x 1      (the bulk density and the weight per volume stay)
//   k_N in Pa         x 1      (k [N/m] = k_Pa x effective length grows with s by itself, so a
//                               bed of the same depth overlaps by the same fraction of a radius:
//                               delta / r = rho g h / k_Pa)
//   k_N in N/m        x s      (what the Pa law would give)
//   restitution, friction, rolling friction, k_T/k_N, eta_T/eta_N   x 1 (dimensionless)
//   eta_N in N s/m    x s^2    (sqrt(m k) with m ~ s^3, k ~ s: the same damping ratio)
//   scene.dt          x s      (the contact period sqrt(m / k) ~ s)
//   fill and insert counts  / s^3 (the same volume of soil), rounded, at least 1
//   skin, close margin: fractions of r_max, unchanged; walls, tools, gravity, region: unchanged
// Cost per simulated second ~ particles / dt ~ s^-4. A checkpoint or a list of particles holds
// grains of their own size: coarse-grain the config that made them instead (refused).
#pragma once

#include "dem/scene.hpp"

namespace YAML {
class Node;
}

namespace dem {

// particles.coarse_grain (the map `particles`, may be null): 1 when absent; refused unless a
// finite factor in [0.1, 10].
double parse_coarse_grain(const YAML::Node& particles);

// Applies the scaling above to the scene (species radii, every contact law, dt).
void coarse_grain_scene(Scene& sc, double factor);

// A particle count for the same volume: count / factor^3, rounded, at least 1 if count >= 1.
long long coarse_grain_count(long long count, double factor);

}  // namespace dem
