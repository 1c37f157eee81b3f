#include "dem/bed.hpp"

#include <algorithm>
#include <cmath>

namespace dem {

SettleResult settle(Engine& engine, State& s, double ke_per_particle, double max_time,
                    const std::function<void(const SettleResult&)>& progress) {
  const Scene& scene = engine.scene();
  const double dt = scene.dt;
  double zmin = 1e300, zmax = -1e300;
  for (const Vec3& x : s.x) {
    zmin = std::min(zmin, x.z);
    zmax = std::max(zmax, x.z);
  }
  const double g = norm(scene.gravity);
  // At rest at the start is not settled: give the top layer time to land first.
  const double min_time = s.size() && g > 0 ? std::sqrt(2 * (zmax - zmin) / g) + 0.02 : 0.0;
  SettleResult r;
  const std::int64_t start = s.step;
  const std::size_t n = std::max<std::size_t>(1, s.size());
  while (true) {
    for (int k = 0; k < 100; ++k) engine.step(s);
    r.time = static_cast<double>(s.step - start) * dt;
    r.ke_per_particle = kinetic_energy(s) / static_cast<double>(n);
    if (progress) progress(r);
    if (r.time >= min_time && r.ke_per_particle < ke_per_particle) {
      r.converged = true;
      return r;
    }
    if (r.time >= max_time) return r;
  }
}

}  // namespace dem
