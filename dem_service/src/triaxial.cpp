#include "dem/triaxial.hpp"

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

// The six walls: 0 xmin, 1 xmax, 2 ymin, 3 ymax, 4 zmin, 5 zmax; normals point inwards.
constexpr int kAxis[6] = {0, 0, 1, 1, 2, 2};

double component(const Vec3& v, int a) { return a == 0 ? v.x : a == 1 ? v.y : v.z; }

struct Box6 {
  Scene& sc;
  double length(int a) const {
    return component(sc.walls[2 * a + 1].point, a) - component(sc.walls[2 * a].point, a);
  }
  double area(int a) const { return length((a + 1) % 3) * length((a + 2) % 3); }
  double volume() const { return length(0) * length(1) * length(2); }
  // Moves wall w inwards by d.
  void move(int w, double d) { sc.walls[w].point += d * sc.walls[w].normal; }
};

// Stress on each wall (Pa) from the engine's wall forces, and each wall's contact count.
void wall_state(const Engine& e, const State& s, Box6& box, double stress[6], int contacts[6]) {
  for (int w = 0; w < 6; ++w) {
    const Wall& wall = box.sc.walls[w];
    stress[w] = -dot(e.wall_forces()[w], wall.normal) / box.area(kAxis[w]);
    contacts[w] = 0;
  }
  for (std::size_t i = 0; i < s.size(); ++i)
    for (int w = 0; w < 6; ++w) {
      const Wall& wall = box.sc.walls[w];
      if (s.radius[i] - dot(s.x[i] - wall.point, wall.normal) > 0) ++contacts[w];
    }
}

}  // namespace

void validate(const TriaxialOptions& o) {
  need(o.grains >= 50 && o.grains <= 2000000, "grains", static_cast<double>(o.grains), "50 to 2e6 grains");
  need(o.radius > 0, "radius", o.radius, "a radius > 0 m");
  need(o.spread >= 0 && o.spread < 0.5, "spread", o.spread, "a relative spread in [0, 0.5)");
  need(o.density > 0, "density", o.density, "a grain density > 0 kg/m^3");
  need(o.stiffness > 0, "stiffness", o.stiffness, "k_N > 0 N/m");
  need(o.restitution > 0 && o.restitution <= 1, "restitution", o.restitution, "a value in (0, 1]");
  need(o.tangential_stiffness_ratio >= 0, "kt-ratio", o.tangential_stiffness_ratio, "k_T / k_N >= 0");
  need(o.friction >= 0, "mu", o.friction, "a Coulomb coefficient >= 0");
  need(o.prep_friction >= 0, "prep-mu", o.prep_friction, "a Coulomb coefficient >= 0");
  need(o.confining > 0, "pressures", o.confining, "confining stresses > 0 Pa");
  need(o.strain_rate > 0 && o.strain_rate <= 1, "rate", o.strain_rate, "an axial strain rate in (0, 1] 1/s");
  need(o.max_strain > 0 && o.max_strain <= 0.5, "max-strain", o.max_strain, "an axial strain in (0, 0.5]");
  need(o.sample_strain > 0 && o.sample_strain <= o.max_strain / 4, "sample-strain", o.sample_strain,
       "a strain > 0 and at most a quarter of --max-strain");
  need(o.threads >= 1 && o.threads <= 256, "threads", o.threads, "1 to 256 threads");
  // Overlap under the confining stress: about sigma_3 d^2 / k_N; more than 5 % of a radius is
  // not a rigid-grain test.
  const double d = 2 * o.radius;
  const double overlap = o.confining * d * d / o.stiffness / o.radius;
  if (overlap > 0.05) {
    std::ostringstream m;
    m << "--pressures: " << o.confining << " Pa presses grains of k_N " << o.stiffness
      << " N/m into each other by about " << overlap
      << " of a radius (sigma_3 d^2 / k_N); keep it below 0.05: raise --stiffness or lower the pressure";
    throw std::invalid_argument(m.str());
  }
}

TriaxialResult run_triaxial(const TriaxialOptions& o,
                            const std::function<void(const char*, double, double, double)>& progress) {
  validate(o);
  Scene sc;
  Species sp;
  sp.name = "grain";
  sp.density = o.density;
  sp.radius.kind = o.spread > 0 ? RadiusDistribution::Kind::uniform : RadiusDistribution::Kind::constant;
  sp.radius.min = o.radius * (1 - o.spread);
  sp.radius.max = o.radius * (1 + o.spread);
  sc.species.push_back(sp);
  sc.gravity = {0, 0, 0};
  sc.threads = o.threads;
  ContactLaw law;
  law.stiffness_per_length = false;
  law.normal_stiffness = o.stiffness;
  law.restitution = o.restitution;
  law.tangential_stiffness_ratio = o.tangential_stiffness_ratio;
  law.friction = o.prep_friction;
  finalize(law, "triaxial");
  sc.particle_particle = law;
  sc.particle_wall = law;
  sc.particle_wall.friction = 0;  // smooth walls
  // The box: grains inserted at a solid fraction of 0.25.
  const double r3 = sp.radius.kind == RadiusDistribution::Kind::uniform
                        ? (std::pow(sp.radius.max, 4) - std::pow(sp.radius.min, 4)) /
                              (4 * (sp.radius.max - sp.radius.min))
                        : std::pow(o.radius, 3);
  const double L0 = std::cbrt(static_cast<double>(o.grains) * 4.0 / 3.0 * M_PI * r3 / 0.25);
  const Vec3 normals[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (int w = 0; w < 6; ++w) {
    Wall wall;
    wall.name = std::string("wall") + std::to_string(w);
    wall.normal = normals[w];
    wall.point = (w % 2) ? Vec3{L0, L0, L0} : Vec3{0, 0, 0};
    sc.walls.push_back(wall);
  }
  sc.dt = 0.999 * largest_safe_dt(sc);
  TriaxialResult res;
  res.dt = sc.dt;
  State s;
  insert_random(sc, {0, {0, 0, 0}, {L0, L0, L0}, o.grains, o.seed}, s, "triaxial sample");
  Box6 box{sc};
  const double dt = sc.dt, target = o.confining;
  double stress[6];
  int contacts[6];
  // Servo: each wall moves so that one step changes its force by a quarter of the error, with
  // the stiffness of its contacts (k_N per contact), at most vmax.
  auto servo = [&](int w, double vmax) {
    const double A = box.area(kAxis[w]);
    double v = 0.25 * A * (target - stress[w]) / (o.stiffness * std::max(contacts[w], 1) * dt);
    v = std::clamp(v, -vmax, vmax);
    box.move(w, v * dt);
  };
  const double energy_scale = target * 8 * o.radius * o.radius * o.radius;  // sigma d^3
  // Isotropic compression with the preparation friction.
  {
    Engine engine(sc);
    const double vmax = 0.5 * L0;
    double t = 0;
    double avg[6] = {};
    int n = 0;
    while (true) {
      engine.step(s);
      wall_state(engine, s, box, stress, contacts);
      for (int w = 0; w < 6; ++w) servo(w, vmax), avg[w] += stress[w];
      t += dt;
      if (++n == 200) {
        bool held = true;
        for (int w = 0; w < 6; ++w) {
          held = held && std::abs(avg[w] / n - target) < 0.01 * target;
          avg[w] = 0;
        }
        n = 0;
        const double ke = kinetic_energy(s) / static_cast<double>(s.size());
        if (progress) progress("compression", t, stress[5], stress[1]);
        if (held && ke < 1e-4 * energy_scale) break;
        if (t > 5.0)
          throw std::runtime_error("triaxial: the isotropic compression did not reach the confining "
                                   "stress at rest in 5 s simulated; lower --pressures or raise --stiffness");
      }
    }
  }
  double solid = 0;
  for (std::size_t i = 0; i < s.size(); ++i) solid += 4.0 / 3.0 * M_PI * std::pow(s.radius[i], 3);
  res.initial_fraction = solid / box.volume();
  // The test friction; the sample relaxes under the servo for a while first.
  sc.particle_particle.friction = o.friction;
  for (std::size_t i = 0; i < s.size(); ++i) s.v[i] = s.u[i] = Vec3{};
  Engine engine(sc);
  const double Lz0 = box.length(2), V0 = box.volume();
  const double vz = 0.5 * o.strain_rate * Lz0;          // each z wall
  const double vside = 20 * o.strain_rate * box.length(0);
  for (int k = 0; k < 2000; ++k) {
    engine.step(s);
    wall_state(engine, s, box, stress, contacts);
    for (int w = 0; w < 6; ++w) servo(w, vside);
  }
  const double Lz_start = box.length(2), V_start = box.volume();
  (void)Lz0;
  (void)V0;
  TriaxialSample acc;
  int n = 0;
  double next = o.sample_strain;
  while (true) {
    engine.step(s);
    wall_state(engine, s, box, stress, contacts);
    for (int w = 0; w < 4; ++w) servo(w, vside);
    box.move(4, vz * dt);
    box.move(5, vz * dt);
    acc.sigma1 += 0.5 * (stress[4] + stress[5]);
    acc.sigma_x += 0.5 * (stress[0] + stress[1]);
    acc.sigma_y += 0.5 * (stress[2] + stress[3]);
    ++n;
    const double strain = (Lz_start - box.length(2)) / Lz_start;
    if (strain >= next) {
      TriaxialSample p;
      p.axial_strain = strain;
      p.volumetric_strain = (V_start - box.volume()) / V_start;
      p.sigma1 = acc.sigma1 / n;
      p.sigma_x = acc.sigma_x / n;
      p.sigma_y = acc.sigma_y / n;
      p.sigma3 = 0.5 * (p.sigma_x + p.sigma_y);
      res.curve.push_back(p);
      res.servo_error = std::max({res.servo_error, std::abs(p.sigma_x - target) / target,
                                  std::abs(p.sigma_y - target) / target});
      if (progress) progress("shear", strain, p.sigma1, p.sigma3);
      acc = TriaxialSample{};
      n = 0;
      next += o.sample_strain;
      if (strain >= o.max_strain) break;
    }
  }
  for (const TriaxialSample& p : res.curve) {
    const double ratio = p.sigma1 / p.sigma3;
    if (ratio > res.peak_ratio) {
      res.peak_ratio = ratio;
      res.peak_strain = p.axial_strain;
    }
  }
  res.peak_phi = std::asin((res.peak_ratio - 1) / (res.peak_ratio + 1));
  const std::size_t from = res.curve.size() - std::max<std::size_t>(1, res.curve.size() / 5);
  double ratio = 0;
  for (std::size_t k = from; k < res.curve.size(); ++k) ratio += res.curve[k].sigma1 / res.curve[k].sigma3;
  ratio /= static_cast<double>(res.curve.size() - from);
  res.final_phi = std::asin((ratio - 1) / (ratio + 1));
  return res;
}

MohrCoulomb mohr_coulomb_fit(const std::vector<double>& s3, const std::vector<double>& s1) {
  if (s3.size() != s1.size() || s3.size() < 2)
    throw std::invalid_argument("Mohr-Coulomb fit: needs two or more tests (three for a check)");
  const double n = static_cast<double>(s3.size());
  double sp = 0, sq = 0, spp = 0, spq = 0;
  for (std::size_t k = 0; k < s3.size(); ++k) {
    const double p = 0.5 * (s1[k] + s3[k]), q = 0.5 * (s1[k] - s3[k]);
    sp += p;
    sq += q;
    spp += p * p;
    spq += p * q;
  }
  const double den = n * spp - sp * sp;
  if (!(std::abs(den) > 0)) throw std::invalid_argument("Mohr-Coulomb fit: the tests share one mean stress");
  const double slope = (n * spq - sp * sq) / den, intercept = (sq - slope * sp) / n;
  MohrCoulomb m;
  m.phi = std::asin(std::clamp(slope, -1.0, 1.0));
  m.cohesion = intercept / std::cos(m.phi);
  return m;
}

}  // namespace dem
