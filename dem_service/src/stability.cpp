#include "dem/stability.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include "dem/contact_law.hpp"
#include "dem/rotation.hpp"

namespace dem {
std::vector<SizeProbe> size_probes(const Scene& scene) {
  std::vector<SizeProbe> probes;
  for (const Species& sp : scene.species) {
    std::vector<double> radii{sp.radius.min, sp.radius.max};
    for (double v : sp.radius.values) radii.push_back(v);
    for (double r : radii)
      if (r > 0) probes.push_back({sp.name, r, sp.mass(r)});
  }
  return probes;
}

double stiffest_contact_period(const Scene& scene, std::string* which) {
  const std::vector<SizeProbe> probes = size_probes(scene);
  double best = INFINITY;
  auto consider = [&](double t, const std::string& what) {
    if (t < best) {
      best = t;
      if (which) *which = what;
    }
  };
  for (const SizeProbe& a : probes) {
    for (const SizeProbe& b : probes) {
      const double len = a.r * b.r / (a.r + b.r), meff = a.m * b.m / (a.m + b.m);
      std::ostringstream w;
      w << "sphere-sphere " << a.name << " r=" << a.r << " / " << b.name << " r=" << b.r;
      consider(stability_period(scene.particle_particle, len, meff), w.str());
    }
    if (!scene.walls.empty() || !scene.tools.empty()) {
      std::ostringstream w;
      w << "sphere-wall " << a.name << " r=" << a.r;
      consider(stability_period(scene.particle_wall, a.r, a.m), w.str());
      for (std::size_t l = 0; l < scene.boundary_laws.size(); ++l)  // walls[].contact, tools[].contact
        consider(stability_period(scene.boundary_laws[l], a.r, a.m),
                 w.str() + " (wall or tool law " + std::to_string(l) + ")");
    }
  }
  {  // the rotating model's tangential and rolling periods (dem/rotation.hpp)
    std::string w;
    const double t = rotating_contact_period(scene, &w);
    consider(t, w);
  }
  return best;
}

double largest_safe_dt(const Scene& scene) {
  return stiffest_contact_period(scene) / scene.stability.min_steps_per_contact;
}

void check_dt(const Scene& scene, std::ostream& warn) {
  std::string which;
  const double tc = stiffest_contact_period(scene, &which);
  const double safe = tc / scene.stability.min_steps_per_contact;
  if (scene.dt <= safe) return;
  std::ostringstream msg;
  msg << "scene.dt = " << scene.dt << " s leaves " << tc / scene.dt
      << " steps per contact for the stiffest contact (" << which << ", contact period " << tc
      << " s); scene.stability.min_steps_per_contact is " << scene.stability.min_steps_per_contact
      << ". Use scene.dt <= " << safe << " s, soften normal_stiffness, or set "
      << "scene.stability.on_violation: warn";
  if (scene.stability.on_violation == DtViolation::refuse)
    throw std::invalid_argument(msg.str());
  warn << "warning: " << msg.str() << "\n";
}

void validate_state(const Scene& scene, const State& s, bool check_overlaps) {
  const std::size_t n = s.size();
  auto where = [&](std::size_t i) {
    std::ostringstream w;
    w << "particle id " << s.id[i] << " at (" << s.x[i].x << ", " << s.x[i].y << ", " << s.x[i].z
      << ")";
    return w.str();
  };
  const double rmax = scene.r_max();
  for (std::size_t i = 0; i < n; ++i) {
    if (!(s.radius[i] > 0) || !std::isfinite(s.radius[i]))
      throw std::invalid_argument(where(i) + ": radius " + std::to_string(s.radius[i]) +
                                  " must be a positive number of metres");
    if (s.radius[i] > rmax * (1 + 1e-12))
      throw std::invalid_argument(where(i) + ": radius " + std::to_string(s.radius[i]) +
                                  " exceeds the largest species radius " + std::to_string(rmax) +
                                  "; widen the species radius distribution");
    if (!(s.mass[i] > 0) || !std::isfinite(s.mass[i]))
      throw std::invalid_argument(where(i) + ": mass must be positive (check the density)");
    if (s.species[i] < 0 || s.species[i] >= static_cast<int>(scene.species.size()))
      throw std::invalid_argument(where(i) + ": unknown species index " +
                                  std::to_string(s.species[i]));
    const Vec3 p = s.x[i], v = s.v[i];
    if (!std::isfinite(p.x + p.y + p.z + v.x + v.y + v.z))
      throw std::invalid_argument(where(i) + ": position or velocity is not finite");
  }
  if (!check_overlaps) return;
  const double tol = scene.stability.overlap_tolerance;
  // Walls.
  for (std::size_t i = 0; i < n; ++i)
    for (const Wall& w : scene.walls) {
      const double overlap = s.radius[i] - dot(s.x[i] - w.point, w.normal);
      if (overlap > tol * s.radius[i])
        throw std::invalid_argument(where(i) + " overlaps wall '" + w.name + "' by " +
                                    std::to_string(overlap) + " m (more than " +
                                    "scene.stability.overlap_tolerance = " + std::to_string(tol) +
                                    " of its radius); move it or the wall");
    }
  // Pairs, through a hash grid with cells of the largest diameter.
  const double h = 2 * rmax;
  auto cell = [&](Vec3 p) {
    return std::array<long, 3>{static_cast<long>(std::floor(p.x / h)),
                               static_cast<long>(std::floor(p.y / h)),
                               static_cast<long>(std::floor(p.z / h))};
  };
  auto key = [](long x, long y, long z) {
    return (static_cast<std::uint64_t>(x & 0x1FFFFF) << 42) |
           (static_cast<std::uint64_t>(y & 0x1FFFFF) << 21) | static_cast<std::uint64_t>(z & 0x1FFFFF);
  };
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> grid;
  grid.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = cell(s.x[i]);
    grid[key(c[0], c[1], c[2])].push_back(i);
  }
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = cell(s.x[i]);
    for (long dz = -1; dz <= 1; ++dz)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dx = -1; dx <= 1; ++dx) {
          const auto it = grid.find(key(c[0] + dx, c[1] + dy, c[2] + dz));
          if (it == grid.end()) continue;
          for (std::size_t j : it->second) {
            if (j <= i) continue;
            const double overlap = s.radius[i] + s.radius[j] - norm(s.x[i] - s.x[j]);
            if (overlap > tol * std::min(s.radius[i], s.radius[j])) {
              std::ostringstream msg;
              msg << where(i) << " and " << where(j) << " overlap by " << overlap
                  << " m, more than scene.stability.overlap_tolerance = " << tol
                  << " of the smaller radius; regenerate the bed (particles.fill) or settle it";
              throw std::invalid_argument(msg.str());
            }
          }
        }
  }
}

}  // namespace dem
