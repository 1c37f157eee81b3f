#include "dem/packing.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <unordered_map>
#include <vector>

#include "cosim/h5.hpp"
#include "cosim/yaml_config.hpp"
#include "dem/bed.hpp"

namespace dem {
namespace h5 = cosim::h5;

namespace {

// A hashed cell grid over points, cell size `cell`.
class CellGrid {
 public:
  explicit CellGrid(double cell) : cell_(cell) {}
  std::int64_t key(long ix, long iy, long iz) const {
    return (static_cast<std::int64_t>(ix) * 73856093) ^ (static_cast<std::int64_t>(iy) * 19349663) ^
           (static_cast<std::int64_t>(iz) * 83492791);
  }
  long c(double v) const { return static_cast<long>(std::floor(v / cell_)); }
  void add(const Vec3& x, std::int32_t i) { cells_[key(c(x.x), c(x.y), c(x.z))].push_back(i); }
  // Calls f(j) for every point in the 27 cells around x (each once: distinct cells may share a
  // hash key, so the visited keys are remembered).
  template <class F>
  void near(const Vec3& x, F&& f) const {
    const long cx = c(x.x), cy = c(x.y), cz = c(x.z);
    std::int64_t seen[27];
    int ns = 0;
    for (long dx = -1; dx <= 1; ++dx)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dz = -1; dz <= 1; ++dz) {
          const std::int64_t k = key(cx + dx, cy + dy, cz + dz);
          if (std::find(seen, seen + ns, k) != seen + ns) continue;
          seen[ns++] = k;
          const auto it = cells_.find(k);
          if (it == cells_.end()) continue;
          for (const std::int32_t j : it->second) f(j);
        }
  }

 private:
  double cell_;
  std::unordered_map<std::int64_t, std::vector<std::int32_t>> cells_;
};

double largest_radius(const State& s) {
  double r = 0;
  for (const double v : s.radius) r = std::max(r, v);
  return r;
}

// Mean of r^3 over a species' distribution.
double mean_r3(const RadiusDistribution& d) {
  switch (d.kind) {
    case RadiusDistribution::Kind::constant:
      return d.min * d.min * d.min;
    case RadiusDistribution::Kind::uniform:
      if (d.max == d.min) return d.min * d.min * d.min;
      return (std::pow(d.max, 4) - std::pow(d.min, 4)) / (4 * (d.max - d.min));
    case RadiusDistribution::Kind::discrete: {
      double m = 0;
      for (std::size_t k = 0; k < d.values.size(); ++k) m += d.weights[k] * std::pow(d.values[k], 3);
      return m;
    }
  }
  return d.min * d.min * d.min;
}

std::string box_text(const Box& b) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "[%.4g, %.4g] x [%.4g, %.4g] x [%.4g, %.4g] m", b.min.x, b.max.x,
                b.min.y, b.max.y, b.min.z, b.max.z);
  return buf;
}

void set_friction(Scene& sc, double mu) {
  sc.particle_particle.friction = mu;
  sc.particle_wall.friction = mu;
  for (ContactLaw& l : sc.boundary_laws) l.friction = mu;
}

}  // namespace

Box inner_region(const State& s, double margin_diameters) {
  if (s.size() == 0) throw std::invalid_argument("packing: the bed has no particles");
  if (!(margin_diameters >= 0) || !std::isfinite(margin_diameters))
    throw std::invalid_argument("packing: the margin must be >= 0 diameters");
  Box b{s.x[0], s.x[0]};
  double rsum = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const Vec3& x = s.x[i];
    b.min = {std::min(b.min.x, x.x), std::min(b.min.y, x.y), std::min(b.min.z, x.z)};
    b.max = {std::max(b.max.x, x.x), std::max(b.max.y, x.y), std::max(b.max.z, x.z)};
    rsum += s.radius[i];
  }
  const double m = margin_diameters * 2 * rsum / static_cast<double>(s.size());
  b.min += Vec3{m, m, m};
  b.max -= Vec3{m, m, m};
  if (!(b.min.x < b.max.x && b.min.y < b.max.y && b.min.z < b.max.z)) {
    std::ostringstream msg;
    msg << "packing: the bed is less than twice the margin (" << margin_diameters
        << " mean diameters = " << m << " m) across in some direction, so no inner region is left "
        << "to measure; use a larger bed or a smaller margin";
    throw std::invalid_argument(msg.str());
  }
  return b;
}

double max_overlap_ratio(const Scene& scene, const State& s) {
  double worst = 0;
  const double rmax = largest_radius(s);
  if (s.size() == 0) return 0;
  CellGrid grid(2 * rmax);
  for (std::size_t i = 0; i < s.size(); ++i) grid.add(s.x[i], static_cast<std::int32_t>(i));
  for (std::size_t i = 0; i < s.size(); ++i) {
    grid.near(s.x[i], [&](std::int32_t j) {
      if (static_cast<std::size_t>(j) <= i) return;
      const double ov = s.radius[i] + s.radius[j] - norm(s.x[i] - s.x[j]);
      if (ov > 0) worst = std::max(worst, ov / std::min(s.radius[i], s.radius[j]));
    });
    for (const Wall& w : scene.walls) {
      const double ov = s.radius[i] - dot(s.x[i] - w.point, w.normal);
      if (ov > 0) worst = std::max(worst, ov / s.radius[i]);
    }
  }
  return worst;
}

PackingStats measure_packing(const Scene& scene, const State& s, const Box& region) {
  PackingStats p;
  p.region = region;
  const double V = region.volume();
  if (!(V > 0)) throw std::invalid_argument("packing: the region to measure has no volume");
  if (s.size() == 0) throw std::invalid_argument("packing: the bed has no particles");
  double rmin = s.radius[0];
  for (const double r : s.radius) rmin = std::min(rmin, r);
  const Vec3 L = region.max - region.min;
  // Sample points: one per cell of a grid of spacing about 1/32 of the smallest diameter
  // (coarser if the region would need more than 8e6 cells), each at a seeded random place in its
  // cell (jittered: a grid in step with a lattice would sample every lattice cell alike). The
  // jitter in x and y is per column of cells, in z per cell.
  const double h = std::max(2 * rmin / 32, std::cbrt(V / 8e6));
  const long nx = std::max(1L, std::lround(L.x / h)), ny = std::max(1L, std::lround(L.y / h)),
             nz = std::max(1L, std::lround(L.z / h));
  const double hx = L.x / nx, hy = L.y / ny, hz = L.z / nz;
  auto jitter = [](std::uint64_t key) {
    std::uint64_t z = key * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return static_cast<double>((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
  };
  const std::size_t cells = static_cast<std::size_t>(nx * ny * nz);
  std::vector<double> zoff(cells), xoff(static_cast<std::size_t>(nx * ny)), yoff(xoff.size());
  for (std::size_t q = 0; q < xoff.size(); ++q) {
    xoff[q] = jitter(2 * q);
    yoff[q] = jitter(2 * q + 1);
  }
  for (std::size_t q = 0; q < cells; ++q) zoff[q] = jitter((q << 2) + 0x51ED27);
  std::vector<std::uint8_t> covered(cells, 0);
  double mass = 0;
  long long hits = 0;
  const double cell_volume = hx * hy * hz;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const Vec3 c = s.x[i] - region.min;
    const double r = s.radius[i];
    const double rho = s.mass[i] / (4.0 / 3.0 * M_PI * r * r * r);
    const long i0 = std::max(0L, static_cast<long>(std::floor((c.x - r) / hx)));
    const long i1 = std::min(nx - 1, static_cast<long>(std::floor((c.x + r) / hx)));
    const long j0 = std::max(0L, static_cast<long>(std::floor((c.y - r) / hy)));
    const long j1 = std::min(ny - 1, static_cast<long>(std::floor((c.y + r) / hy)));
    for (long a = i0; a <= i1; ++a) {
      for (long b = j0; b <= j1; ++b) {
        const std::size_t col = static_cast<std::size_t>(a * ny + b);
        const double dx = (a + xoff[col]) * hx - c.x, dy = (b + yoff[col]) * hy - c.y;
        const double q = r * r - dx * dx - dy * dy;
        if (q < 0) continue;
        const double dz = std::sqrt(q);
        const long k0 = std::max(0L, static_cast<long>(std::floor((c.z - dz) / hz)));
        const long k1 = std::min(nz - 1, static_cast<long>(std::floor((c.z + dz) / hz)));
        for (long k = k0; k <= k1; ++k) {
          const std::size_t cell = col * static_cast<std::size_t>(nz) + static_cast<std::size_t>(k);
          const double z = (k + zoff[cell]) * hz - c.z;
          if (z * z > q) continue;
          std::uint8_t& cv = covered[cell];
          if (cv) continue;
          cv = 1;
          ++hits;
          mass += rho * cell_volume;
        }
      }
    }
  }
  p.fraction = static_cast<double>(hits) / static_cast<double>(covered.size());
  p.bulk_density = mass / V;

  // Contacts of the grains whose centre lies in the region (their partners anywhere).
  const double rmax = largest_radius(s);
  CellGrid grid(2 * rmax);
  for (std::size_t i = 0; i < s.size(); ++i) grid.add(s.x[i], static_cast<std::int32_t>(i));
  long long contacts = 0, rattlers = 0;
  auto inside = [&](const Vec3& x) {
    return x.x >= region.min.x && x.x < region.max.x && x.y >= region.min.y && x.y < region.max.y &&
           x.z >= region.min.z && x.z < region.max.z;
  };
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (!inside(s.x[i])) continue;
    int z = 0;
    grid.near(s.x[i], [&](std::int32_t j) {
      if (static_cast<std::size_t>(j) == i) return;
      const double reach = (s.radius[i] + s.radius[j]) * (1 + kContactGap);
      if (norm2(s.x[i] - s.x[j]) <= reach * reach) ++z;
    });
    contacts += z;
    if (z < 2) ++rattlers;
    ++p.grains;
  }
  if (p.grains > 0) {
    p.coordination = static_cast<double>(contacts) / static_cast<double>(p.grains);
    p.rattlers = static_cast<double>(rattlers) / static_cast<double>(p.grains);
  }
  p.max_overlap_ratio = max_overlap_ratio(scene, s);
  return p;
}

std::string describe(const PackingStats& p) {
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "packing fraction %.4f, bulk density %.0f kg/m^3, coordination %.2f (rattlers "
                "%.1f %%), %lld grains in %s; largest overlap %.3g of a radius",
                p.fraction, p.bulk_density, p.coordination, 100 * p.rattlers, p.grains,
                box_text(p.region).c_str(), p.max_overlap_ratio);
  return buf;
}

void insert_random(const Scene& scene, const InsertRegion& region, State& s, const std::string& path) {
  if (region.species < 0 || static_cast<std::size_t>(region.species) >= scene.species.size())
    throw cosim::config::ConfigError(path + ".species: unknown species");
  const Species& sp = scene.species[region.species];
  const double rmax = std::max(sp.radius.max, sp.radius.min);
  const Vec3 L = region.max - region.min;
  if (!(L.x > 2 * rmax && L.y > 2 * rmax && L.z > 2 * rmax)) {
    std::ostringstream msg;
    msg << path << ": the region must be more than one diameter (" << 2 * rmax
        << " m) across in x, y and z (max above min)";
    throw cosim::config::ConfigError(msg.str());
  }
  if (region.count <= 0) return;
  const double solid = static_cast<double>(region.count) * 4.0 / 3.0 * M_PI * mean_r3(sp.radius);
  const double area = L.x * L.y;
  if (solid > kMaxInsertionFraction * area * L.z || !(L.x * L.y * L.z < 1e12 * rmax * rmax * rmax)) {
    std::ostringstream msg;
    msg << path << ": " << region.count << " grains of '" << sp.name << "' are "
        << solid / (area * L.z) << " of the region's volume; random insertion holds at most "
        << kMaxInsertionFraction << ": raise max.z to at least "
        << region.min.z + solid / (kMaxInsertionFraction * area) + 2 * rmax
        << " m (the grains fall and pack during the deposition) or lower count";
    throw cosim::config::ConfigError(msg.str());
  }
  std::uint64_t rng = region.seed * 0x2545F4914F6CDD1Dull + 0x5A17;
  CellGrid grid(2 * rmax);
  // Grains already there (a loaded bed, earlier regions) that could touch the new ones.
  const double reach = 2 * std::max(rmax, largest_radius(s));
  for (std::size_t j = 0; j < s.size(); ++j) {
    const Vec3& x = s.x[j];
    if (x.x > region.min.x - reach && x.x < region.max.x + reach && x.y > region.min.y - reach &&
        x.y < region.max.y + reach && x.z > region.min.z - reach && x.z < region.max.z + reach)
      grid.add(x, static_cast<std::int32_t>(j));
  }
  // A loaded grain larger than this species' largest would escape the 27-cell search.
  if (largest_radius(s) > rmax) {
    CellGrid wide(2 * largest_radius(s));
    grid = wide;
    for (std::size_t j = 0; j < s.size(); ++j) grid.add(s.x[j], static_cast<std::int32_t>(j));
  }
  std::int64_t next_id = s.id.empty() ? 0 : *std::max_element(s.id.begin(), s.id.end()) + 1;
  constexpr int kAttempts = 100000;
  for (long long n = 0; n < region.count; ++n) {
    const double r = sample_radius(sp, rng);
    bool placed = false;
    for (int a = 0; a < kAttempts && !placed; ++a) {
      const Vec3 x{region.min.x + r + (L.x - 2 * r) * uniform01(rng),
                   region.min.y + r + (L.y - 2 * r) * uniform01(rng),
                   region.min.z + r + (L.z - 2 * r) * uniform01(rng)};
      bool free = true;
      grid.near(x, [&](std::int32_t j) {
        if (!free) return;
        const double d = r + s.radius[j];
        if (norm2(x - s.x[j]) < d * d) free = false;
      });
      if (!free) continue;
      add_particle(s, x, {}, r, sp.mass(r), region.species, next_id++);
      grid.add(x, static_cast<std::int32_t>(s.size() - 1));
      placed = true;
    }
    if (!placed) {
      std::ostringstream msg;
      msg << path << ": no free place found for grain " << n + 1 << " of " << region.count
          << " after " << kAttempts << " random tries; raise max.z (a taller region) or lower count";
      throw cosim::config::ConfigError(msg.str());
    }
  }
}

PrepareResult prepare_bed(const Scene& scene, State& s, const PrepareOptions& o,
                          const std::function<void(const char*, double, double)>& progress) {
  PrepareResult res;
  // Stage 1: the fall, every law with the deposition friction.
  Scene fall = scene;
  set_friction(fall, o.deposition_friction);
  {
    Engine engine(fall);
    const SettleResult r = settle(engine, s, o.ke_per_particle, o.max_time, [&](const SettleResult& p) {
      if (progress) progress("deposition", p.time, p.ke_per_particle);
    });
    res.deposition_time = r.time;
    res.deposition_converged = r.converged;
  }
  // Stage 2: frozen into contact with the scene's own laws: start at rest, settle again.
  for (std::size_t i = 0; i < s.size(); ++i) s.v[i] = s.u[i] = Vec3{};
  {
    // The grains are in place already: no waiting for a fall (settle()'s minimum time), only
    // for the contacts to take up the new law; at rest after at least 200 steps.
    Engine engine(scene);
    const std::int64_t start = s.step;
    const double n = static_cast<double>(std::max<std::size_t>(1, s.size()));
    while (true) {
      for (int k = 0; k < 100; ++k) engine.step(s);
      res.freeze_time = static_cast<double>(s.step - start) * scene.dt;
      const double ke = kinetic_energy(s) / n;
      if (progress) progress("freeze", res.freeze_time, ke);
      if (s.step - start >= 200 && ke < o.ke_per_particle) {
        res.freeze_converged = true;
        break;
      }
      if (res.freeze_time >= o.max_time) break;
    }
  }
  res.packing = measure_packing(scene, s, inner_region(s, o.margin));
  return res;
}

namespace {

void put_attribute(hid_t loc, const std::string& name, double value) {
  if (H5Aexists(loc, name.c_str()) > 0) H5Adelete(loc, name.c_str());
  h5::write_double_attribute(loc, name, value);
}

}  // namespace

void write_bed_record(const std::string& path, double max_overlap,
                      const std::optional<PackingStats>& packing) {
  h5::Handle file(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) throw std::runtime_error("cannot open " + path + " to record the bed's packing");
  const bool exists = H5Lexists(file, "bed", H5P_DEFAULT) > 0;
  h5::Handle group(exists ? H5Gopen2(file, "bed", H5P_DEFAULT)
                          : H5Gcreate2(file, "bed", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                   H5Gclose);
  if (!group.ok()) throw std::runtime_error("cannot write the group /bed in " + path);
  put_attribute(group, "max_overlap_ratio", max_overlap);
  if (packing) {
    put_attribute(group, "packing_fraction", packing->fraction);
    put_attribute(group, "bulk_density", packing->bulk_density);
    put_attribute(group, "coordination", packing->coordination);
    put_attribute(group, "rattlers", packing->rattlers);
    put_attribute(group, "grains_measured", static_cast<double>(packing->grains));
    const Box& b = packing->region;
    const double lo[3] = {b.min.x, b.min.y, b.min.z}, hi[3] = {b.max.x, b.max.y, b.max.z};
    const char* axes[3] = {"x", "y", "z"};
    for (int a = 0; a < 3; ++a) {
      put_attribute(group, std::string("region_min_") + axes[a], lo[a]);
      put_attribute(group, std::string("region_max_") + axes[a], hi[a]);
    }
  }
}

std::optional<double> read_bed_overlap(const std::string& path) {
  h5::Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok() || H5Lexists(file, "bed", H5P_DEFAULT) <= 0) return std::nullopt;
  h5::Handle group(H5Gopen2(file, "bed", H5P_DEFAULT), H5Gclose);
  if (!group.ok() || H5Aexists(group, "max_overlap_ratio") <= 0) return std::nullopt;
  h5::Handle attr(H5Aopen(group, "max_overlap_ratio", H5P_DEFAULT), H5Aclose);
  double v = 0;
  if (!attr.ok() || H5Aread(attr, H5T_NATIVE_DOUBLE, &v) < 0 || !std::isfinite(v) || v < 0)
    return std::nullopt;
  return v;
}

}  // namespace dem
