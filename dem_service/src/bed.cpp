#include "dem/bed.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <numeric>
#include <sstream>

#include "cosim/yaml_config.hpp"

namespace dem {

double uniform01(std::uint64_t& rng) {
  std::uint64_t z = (rng += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return static_cast<double>((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
}

namespace {


std::string gb(double bytes) {
  std::ostringstream o;
  if (bytes >= 100e9) o << std::fixed << std::setprecision(0);
  else o << std::setprecision(3);
  o << bytes / 1e9 << " GB (" << std::fixed;
  o.precision(0);
  o << bytes << " bytes)";
  return o.str();
}

// A "Key:   value kB" line of a /proc file, in bytes; -1 if missing.
double proc_kb(const char* file, const std::string& key) {
  std::ifstream in(file);
  std::string k;
  while (in >> k) {
    if (k == key) {
      double kb = -1;
      in >> kb;
      return kb * 1024;
    }
    in.ignore(4096, '\n');
  }
  return -1;
}

}  // namespace

double available_memory_bytes(std::string* source) {
  double avail = proc_kb("/proc/meminfo", "MemAvailable:");
  if (source) *source = "MemAvailable in /proc/meminfo";
  rlimit as{};
  if (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
    const double used = std::max(0.0, proc_kb("/proc/self/status", "VmSize:"));
    const double left = std::max(0.0, static_cast<double>(as.rlim_cur) - used);
    if (avail < 0 || left < avail) {
      avail = left;
      if (source) *source = "the address-space limit (RLIMIT_AS, ulimit -v) less the " + gb(used) + " in use";
    }
  }
  return std::max(0.0, avail);
}

void check_memory_for_particles(double particles, const std::string& key) {
  std::string source;
  const double avail = available_memory_bytes(&source);
  const double need = particles * kBytesPerParticle;
  if (avail <= 0 || need <= avail) return;
  std::ostringstream msg;
  msg << key << ": a scene of " << particles << " particles needs at least " << gb(need) << " of memory ("
      << kBytesPerParticle << " B per particle: state, contact lists and workspace) but "
      << gb(avail) << " are available (" << source
      << "): lower the count, or run where more memory is free";
  throw cosim::config::ConfigError(msg.str());
}

double sample_radius(const Species& sp, std::uint64_t& rng) {
  const RadiusDistribution& d = sp.radius;
  switch (d.kind) {
    case RadiusDistribution::Kind::constant:
      return d.min;
    case RadiusDistribution::Kind::uniform:
      return d.min + (d.max - d.min) * uniform01(rng);
    case RadiusDistribution::Kind::discrete: {
      double u = uniform01(rng), acc = 0;
      for (std::size_t k = 0; k < d.values.size(); ++k) {
        acc += d.weights[k];
        if (u < acc) return d.values[k];
      }
      return d.values.back();
    }
  }
  return d.min;
}

void fill_region(const Scene& scene, const FillRegion& region, State& s) {
  const Species& sp = scene.species[region.species];
  const double rmax = std::max(sp.radius.max, sp.radius.min);
  // 15 % slack: the jitter is large enough that settling columns collapse into a random
  // packing instead of staying stacked, and neighbours can never overlap.
  const double pitch = 2 * rmax * 1.15;
  // Half a pitch from the region's faces: a jittered particle stays inside the region.
  const double e = pitch / 2;
  const Vec3 lo = region.min + Vec3{e, e, e}, hi = region.max - Vec3{e, e, e};
  // A lattice layer of more than 1e7 cells (a 70 m square at a 1 cm radius; a 1M-particle bed
  // needs about 1e5) is a region in the wrong units, and the layer's shuffle would take its
  // size in memory: refuse it before counting in integers.
  const double layer = (std::floor((hi.x - lo.x) / pitch) + 1) * (std::floor((hi.y - lo.y) / pitch) + 1);
  if (!(layer <= 1e7) || !(std::floor((hi.z - lo.z) / pitch) + 1 <= 1e7)) {
    std::ostringstream msg;
    msg << "particles.fill: region [" << region.min.x << ", " << region.min.y << ", " << region.min.z
        << "] .. [" << region.max.x << ", " << region.max.y << ", " << region.max.z
        << "] m is more than 1e7 lattice cells (pitch " << pitch
        << " m) across: give min and max in metres around where the particles go";
    throw cosim::config::ConfigError(msg.str());
  }
  const long nx = static_cast<long>(std::floor((hi.x - lo.x) / pitch)) + 1;
  const long ny = static_cast<long>(std::floor((hi.y - lo.y) / pitch)) + 1;
  const long nz = static_cast<long>(std::floor((hi.z - lo.z) / pitch)) + 1;
  if (hi.x < lo.x || hi.y < lo.y || hi.z < lo.z || nx * ny * nz < region.count) {
    std::ostringstream msg;
    msg << "particles.fill: region holds at most "
        << (hi.x < lo.x || hi.y < lo.y || hi.z < lo.z ? 0 : nx * ny * nz) << " particles of '"
        << sp.name << "' (lattice pitch " << pitch << " m) but count is " << region.count
        << "; enlarge the region or lower count";
    throw cosim::config::ConfigError(msg.str());
  }
  check_memory_for_particles(static_cast<double>(s.size()) + static_cast<double>(region.count),
                             "particles.fill (count " + std::to_string(region.count) + ")");
  std::uint64_t rng = region.seed * 0x2545F4914F6CDD1Dull + 12345;
  long long placed = 0;
  std::int64_t next_id = s.id.empty() ? 0 : *std::max_element(s.id.begin(), s.id.end()) + 1;
  for (long iz = 0; iz < nz && placed < region.count; ++iz) {
    // Random order within a layer so a partly filled top layer is not one-sided.
    std::vector<long> cells(static_cast<std::size_t>(nx * ny));
    std::iota(cells.begin(), cells.end(), 0);
    for (std::size_t k = cells.size(); k > 1; --k)
      std::swap(cells[k - 1], cells[static_cast<std::size_t>(uniform01(rng) * k)]);
    for (long c : cells) {
      if (placed >= region.count) break;
      const double r = sample_radius(sp, rng);
      const double slack = pitch / 2 - r;  // room to jitter without touching a neighbour
      const Vec3 centre{lo.x + (c % nx) * pitch, lo.y + (c / nx) * pitch, lo.z + iz * pitch};
      const Vec3 jitter{slack * (2 * uniform01(rng) - 1), slack * (2 * uniform01(rng) - 1),
                        slack * (2 * uniform01(rng) - 1)};
      add_particle(s, centre + 0.999 * jitter, {}, r, sp.mass(r), region.species, next_id++);
      ++placed;
    }
  }
}


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
