#include "dem/repose.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "dem/engine.hpp"
#include "dem/packing.hpp"
#include "dem/stability.hpp"

namespace dem {

namespace {

void need(bool ok, const std::string& option, double value, const std::string& range) {
  if (ok && std::isfinite(value)) return;
  std::ostringstream m;
  m << "--" << option << " = " << value << " is not allowed: give " << range;
  throw std::invalid_argument(m.str());
}

Wall plane(const char* name, Vec3 point, Vec3 normal, int law) {
  Wall w;
  w.name = name;
  w.point = point;
  w.normal = normal;
  w.law = law;
  return w;
}

}  // namespace

void validate(const ReposeOptions& o) {
  need(o.grains >= 100 && o.grains <= 2000000, "grains", static_cast<double>(o.grains), "100 to 2e6 grains");
  need(o.radius > 0, "radius", o.radius, "a radius > 0 m");
  need(o.spread >= 0 && o.spread < 0.5, "spread", o.spread, "a relative spread in [0, 0.5)");
  need(o.density > 0, "density", o.density, "a grain density > 0 kg/m^3");
  need(o.stiffness > 0, "stiffness", o.stiffness, "k_N > 0 N/m");
  need(o.restitution > 0 && o.restitution <= 1, "restitution", o.restitution, "a value in (0, 1]");
  need(o.tangential_stiffness_ratio >= 0, "kt-ratio", o.tangential_stiffness_ratio, "k_T / k_N >= 0");
  need(o.friction >= 0, "mu", o.friction, "a Coulomb coefficient >= 0");
  need(o.deposition_friction >= 0, "deposition-mu", o.deposition_friction, "a Coulomb coefficient >= 0");
  need(o.length >= 8 * o.radius, "length", o.length, "a column length of at least 4 diameters");
  need(o.width >= 12 * o.radius, "width", o.width, "a width of at least 6 diameters (m)");
  need(o.max_time > 0 && o.max_time <= 100, "max-time", o.max_time, "a time in (0, 100] s");
  need(o.threads >= 1 && o.threads <= 256, "threads", o.threads, "1 to 256 threads");
}

ReposeResult run_repose(const ReposeOptions& o) {
  validate(o);
  Scene sc;
  Species sp;
  sp.name = "grain";
  sp.density = o.density;
  sp.radius.kind = o.spread > 0 ? RadiusDistribution::Kind::uniform : RadiusDistribution::Kind::constant;
  sp.radius.min = o.radius * (1 - o.spread);
  sp.radius.max = o.radius * (1 + o.spread);
  sc.species.push_back(sp);
  sc.threads = o.threads;
  ContactLaw law;
  law.stiffness_per_length = false;
  law.normal_stiffness = o.stiffness;
  law.restitution = o.restitution;
  law.tangential_stiffness_ratio = o.tangential_stiffness_ratio;
  law.friction = o.friction;
  finalize(law, "repose");
  sc.particle_particle = sc.particle_wall = law;  // the floor: rough like the grains
  ContactLaw smooth = law;
  smooth.friction = 0;
  sc.boundary_laws.push_back(smooth);  // the side and back walls and the gate
  sc.walls.push_back(plane("floor", {0, 0, 0}, {0, 0, 1}, -1));
  sc.walls.push_back(plane("back", {0, 0, 0}, {1, 0, 0}, 0));  // smooth: no grains hung on it
  sc.walls.push_back(plane("left", {0, 0, 0}, {0, 1, 0}, 0));
  sc.walls.push_back(plane("right", {0, o.width, 0}, {0, -1, 0}, 0));
  sc.walls.push_back(plane("gate", {o.length, 0, 0}, {-1, 0, 0}, 0));
  sc.dt = 0.999 * largest_safe_dt(sc);
  // Inserted at a solid fraction of 0.25, deposited, frozen with the test friction.
  const double r3 = o.spread > 0 ? (std::pow(sp.radius.max, 4) - std::pow(sp.radius.min, 4)) /
                                       (4 * (sp.radius.max - sp.radius.min))
                                 : std::pow(o.radius, 3);
  const double height = static_cast<double>(o.grains) * 4.0 / 3.0 * M_PI * r3 / (0.25 * o.length * o.width) +
                        2 * sp.radius.max;
  State s;
  insert_random(sc, {0, {0, 0, 0}, {o.length, o.width, height}, o.grains, o.seed}, s, "repose column");
  PrepareOptions prep;
  prep.enabled = true;
  prep.deposition_friction = o.deposition_friction;
  prep.ke_per_particle = 1e-8;
  prep.max_time = 5;
  prep.margin = 2.0;
  ReposeResult res;
  const PrepareResult pr = prepare_bed(sc, s, prep);
  res.column_fraction = pr.packing.fraction;
  auto top = [&]() {
    double z = 0;
    for (std::size_t i = 0; i < s.size(); ++i) z = std::max(z, s.x[i].z + s.radius[i]);
    return z;
  };
  res.column_height = top();
  // Release: the gate goes far away.
  sc.walls[4].point.x = 1e3;
  Engine engine(sc);
  const double n = static_cast<double>(s.size());
  double t = 0;
  while (t < o.max_time) {
    for (int k = 0; k < 100; ++k) engine.step(s);
    t += 100 * sc.dt;
    if (t > 0.2 && kinetic_energy(s) / n < 1e-8) {
      res.at_rest = true;
      break;
    }
  }
  // The surface: the highest grain top per slice of one mean diameter along x.
  const double d = 2 * o.radius;
  double xmax = 0;
  for (const Vec3& x : s.x) xmax = std::max(xmax, x.x);
  const std::size_t bins = static_cast<std::size_t>(xmax / d) + 1;
  std::vector<double> h(bins, 0);
  for (std::size_t i = 0; i < s.size(); ++i) {
    const long b = static_cast<long>(s.x[i].x / d);
    if (b >= 0 && static_cast<std::size_t>(b) < bins)
      h[static_cast<std::size_t>(b)] = std::max(h[static_cast<std::size_t>(b)], s.x[i].z + s.radius[i]);
  }
  // The first two slices are the layer against the back wall: grains that do not rotate stand
  // there in a column one grain wide (even against a smooth wall), taller than the heap.
  constexpr std::size_t kWallSlices = 2;
  const double H = bins > kWallSlices ? *std::max_element(h.begin() + kWallSlices, h.end()) : 0.0;
  res.final_height = H;
  // The band fitted: 20 % to 80 % of the heap's height, but not the sheet of one or two grains
  // that runs far out over the floor (below 3 diameters).
  const double low = std::max(0.2 * H, 3 * d);
  // From the wall layer out to where the heap ends (the first slice below 10 % of the height).
  double sx = 0, sz = 0, sxx = 0, sxz = 0;
  int m = 0;
  for (std::size_t b = 0; b < bins; ++b) {
    res.profile_x.push_back((b + 0.5) * d);
    res.profile_z.push_back(h[b]);
    if (b < kWallSlices) continue;
    if (h[b] < 0.1 * H) break;
    if (h[b] > 0.8 * H || h[b] < low) continue;
    const double x = (b + 0.5) * d;
    sx += x, sz += h[b], sxx += x * x, sxz += x * h[b];
    ++m;
  }
  res.surface_points = m;
  res.angle = NAN;  // fewer than 3 surface points: no slope (the column stood, or ran flat)
  if (m >= 3) {
    const double slope = (m * sxz - sx * sz) / (m * sxx - sx * sx), icpt = (sz - slope * sx) / m;
    res.angle = std::atan(-slope);
    double ss = 0;
    for (std::size_t b = kWallSlices; b < res.profile_z.size(); ++b) {
      if (h[b] > 0.8 * H || h[b] < low) continue;
      const double e = h[b] - (icpt + slope * res.profile_x[b]);
      ss += e * e;
    }
    res.fit_rms = std::sqrt(ss / m);
  }
  return res;
}

}  // namespace dem
